"""drapebench: a reproduction and comparison suite for neural garment draping.

Sub-packages: ``body`` (SMPL-format body model, Anny bake, motions), ``geometry`` (mesh topology,
proximity), ``garments`` (parametric garment factory), ``physics`` (material, energies),
``reference`` (Newton physics-based reference simulator), ``data`` (typed training data), plus ``metrics``,
``results`` (the run record), ``viz``, ``report`` and ``experiment`` (the pipeline behind ``run.py``).
"""

__version__ = "0.1.0"
