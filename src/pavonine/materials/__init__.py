"""The peacock-feather optics model (paper §3.1–3.2, Eq. 1–7) and its parameters."""
