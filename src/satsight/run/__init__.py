"""A dataset run: the output folder, resuming, shards, and the frame engines that fill it
(in this process, or on a Dask cluster)."""
