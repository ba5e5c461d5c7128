"""GAPS, its SNUG-like / NCS-like ablations, and the optimum of its loss (``gaps_optimum``)."""

from methods.gaps.method import GAPS
from methods.gaps.optimum import GapsOptimum

__all__ = ["GAPS", "GapsOptimum"]
