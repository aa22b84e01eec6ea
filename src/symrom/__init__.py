"""symrom: symbolic reduced-order models of legged-robot jumping learned from data."""

__version__ = "0.1.0"
