from cobot_analysis.cli import main

main()
