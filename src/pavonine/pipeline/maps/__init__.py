"""The feather's six data maps (paper §3.3): procedural painting and image I/O."""
