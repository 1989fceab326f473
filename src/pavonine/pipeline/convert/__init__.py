"""Recipes and maps in, USD feather component assets out: recipe parsing, the feather mesh,
asset layers and the (batch) converter."""
