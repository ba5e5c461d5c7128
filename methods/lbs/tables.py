"""The committed table of the skinning baseline: the zero point every method's table stands on (one
:class:`drapebench.table_specs.TableSpec`, found through :mod:`drapebench.plugins`)."""

from drapebench.table_specs import Sweep, TableSpec

TABLES = [
    TableSpec("baseline", "the lbs zero point on four garments, walking", ("eps_e", "eps_a", "eps_c"),
              sweeps=(Sweep("baseline"),)),
]
