"""GenSim: motion-aware ARAP + Physics Enforcing Network (see README.md beside this file)."""

from methods.gensim.method import GenSim

__all__ = ["GenSim"]
