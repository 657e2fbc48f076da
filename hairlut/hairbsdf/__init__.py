"""A physically based hair BSDF (Chiang et al. 2016, after d'Eon et al. 2011) and its converged lookup tables.

Minimal placeholder: the table kind's helper owns this package's public list (issue 28)."""

__all__ = []
