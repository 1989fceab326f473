"""Assemblies of feather components: the displaying peacock train (recipe, fan layout, USD)."""
