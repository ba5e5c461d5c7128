"""The claims the scoreboard judges: each method's, declared beside its code in its package's ``claims.py``
(:mod:`drapebench.plugins`), every method's ``CLAIMS`` first, then every method's ``MORE_CLAIMS``."""

from drapebench.claim import Claim
from drapebench.plugins import declared


def claims() -> list[Claim]:
    """Every registered method's claims, in the scoreboard's order; ValueError naming a claim id two claims share."""
    out = [c for attr in ("CLAIMS", "MORE_CLAIMS") for _, found in declared("claims", attr) for c in found]
    ids = [c.id for c in out]
    twice = sorted({i for i in ids if ids.count(i) > 1})
    if twice:
        raise ValueError(f"claim ids declared twice: {', '.join(twice)}")
    return out
