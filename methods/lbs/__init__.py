"""The ``lbs`` baseline: the template skinned rigidly with the body, nothing learned."""

from methods.lbs.method import LBSMethod

__all__ = ["LBSMethod"]
