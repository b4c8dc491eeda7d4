"""Finite-element and contact machinery shared by the scenes (no scene here)."""
