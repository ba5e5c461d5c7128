"""GAPS and its SNUG-like / NCS-like ablations."""

from methods.gaps.method import GAPS

__all__ = ["GAPS"]
