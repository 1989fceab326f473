"""A feather asset packed for elsewhere: one ``.usdz`` file (USD's own packaging) and glTF 2.0
binaries for game engines and the web."""
