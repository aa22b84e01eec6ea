"""Jumps to a target planned with a model and executed in simulation (docs/design.md, "Planning a jump")."""
