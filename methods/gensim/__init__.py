"""GenSim: motion-aware ARAP + Physics Enforcing Network, and the optimum of its loss (``gensim_optimum``; see README.md beside this file)."""

from methods.gensim.method import GenSim
from methods.gensim.optimum import GensimOptimum

__all__ = ["GenSim", "GensimOptimum"]
