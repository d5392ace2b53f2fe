"""Offline half of the vision interface (Lee et al. §5.3): the silhouette bank."""
