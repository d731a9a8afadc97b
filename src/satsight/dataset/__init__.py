"""Labels and files: what a dataset holds and how it is written."""
