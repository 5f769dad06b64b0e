"""Matplotlib figures (never imported by core modules)."""
