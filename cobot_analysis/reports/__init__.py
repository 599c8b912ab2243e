"""Report builders and the figure style of the analyses."""
