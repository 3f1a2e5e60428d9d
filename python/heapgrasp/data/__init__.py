"""Datasets generated in simulation from a root seed (the critic's today)."""
