"""Statistics of the studies (docs/methods.md sec. 4): tests with effect sizes (``tests``), the declarative
analyses of ``pipelines/*.toml`` (``config``), the data each question runs on (``sources``), the
runner with Holm correction (``analyses``) and the largest indistinguishable subset (``subsets``)."""
