"""Batches on a farm: frame ranges, turntables, cameras and products as render jobs, run in this
process or on a Dask cluster (embedded LocalCluster or an existing scheduler), split by samples
and merged exactly, outputs written atomically by the client; conversions on the cluster too.
See docs/farm.md."""
