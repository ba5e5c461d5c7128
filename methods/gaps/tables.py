"""The committed tables of GAPS's experiments (its paper's Tables 1-4, held-out motion and shapes, generalisation):
one :class:`drapebench.table_specs.TableSpec` each, which ``drapebench.report`` and ``drapebench.reproduce`` find
through :mod:`drapebench.plugins`."""

from drapebench.table_specs import ONE_THREAD, SEEDS, Sweep, TableSpec, untrained

# --quick (a pipeline check, untrained): the canonical relaxation on 2 body shapes of 20 L-BFGS iterations each, not
# 9 of 200 (7-12 s each; 476 core-s of CI's quick run)
QUICK = ("method.params.relax_components=1", "method.params.relax_grid=[-2.0,2.0]", "method.params.relax_iterations=20")

NO_INEXT_OPTIMUM = ("method=gaps_optimum", "method.name=gaps_no_inext_optimum", "method.params.inextensibility_weight=0.0",
                    "method.params.relax_inextensibility_weight=2.0e+8")  # fmt: skip

# the held-out tables (a column group per held-out motion and body shape): vertex error, strain and collisions
# against the untrained skinning, GAPS's own loss (trained, untrained, and the optimum's row) and the loss gap closed
HELDOUT_METRICS = ("vertex_error_mm", "vertex_error_mm@untrained", "eps_e", "eps_e@untrained", "eps_c", "eps_c@postprocessed",
                   "gaps_loss", "gaps_loss@untrained", "loss_gap_closed")

TABLES = [
    TableSpec("gaps_table1", "GAPS Table 1: ε_e, ε_a, ε_c of SNUG, NCS and GAPS (before the push-out, and after it), "
              "their untrained skinnings, GAPS's loss optimum, lbs and pbs on four garments, held-out kick",
              ("eps_e", "eps_a", "eps_c", "eps_c@postprocessed"),
              sweeps=(Sweep("gaps_table1", ("method=snug_like,ncs_like,gaps", SEEDS, ONE_THREAD)),
                      Sweep("gaps_table1", ("method=lbs,pbs", ONE_THREAD)),
                      *untrained("gaps_table1", ("gaps", "ncs_like", "snug_like")),
                      Sweep("gaps_table1", ("method=gaps_optimum", ONE_THREAD))),
              methods=("lbs", "pbs", "snug_like", "snug_like_untrained", "ncs_like", "ncs_like_untrained", "gaps", "gaps_untrained",
                       "gaps_optimum")),  # fmt: skip
    TableSpec("gaps_table2", "GAPS Table 2: ε_c of GAPS, k_ext = 1 and without L_inext, each loss's optimum and GAPS's "
              "untrained skinning (the claims' control), and the share of its loss's gap each training closes", ("eps_c", "loss_gap_closed"),
              sweeps=(Sweep("gaps_table2", (SEEDS, ONE_THREAD)),
                      *untrained("gaps_table2", ("gaps",)),
                      Sweep("gaps_table2", ("method=gaps_optimum", ONE_THREAD)),
                      Sweep("gaps_table2", ("method=gaps_optimum", "method.name=gaps_kext1_optimum", "method.params.kext=one", ONE_THREAD)),
                      Sweep("gaps_table2", (*NO_INEXT_OPTIMUM, ONE_THREAD))),
              methods=("gaps", "gaps_kext1", "gaps_no_inext", "gaps_untrained", "gaps_optimum", "gaps_kext1_optimum",
                       "gaps_no_inext_optimum")),  # fmt: skip
    TableSpec("gaps_table3", "GAPS Table 3: ε_e, ε_a of the dress on an average, a heavy and a very heavy body, with and "
              "without L_inext, each loss's optimum and the untrained skinning, and the share of its loss's gap each training closes",
              ("eps_e", "eps_a", "eps_c", "loss_gap_closed"), group="shape",
              sweeps=(Sweep("gaps_table3", (SEEDS, ONE_THREAD)), *untrained("gaps_table3", ("gaps",)),
                      Sweep("gaps_table3", ("method=gaps_optimum", ONE_THREAD)), Sweep("gaps_table3", (*NO_INEXT_OPTIMUM, ONE_THREAD))),
              methods=("gaps", "gaps_no_inext", "gaps_untrained", "gaps_optimum", "gaps_no_inext_optimum")),  # fmt: skip
    TableSpec("gaps_table4", "GAPS Table 4: training time, time to converge and drape time of Table 1's runs",
              ("train_s", "converged_s", "ms_per_frame"), sweeps_of="gaps_table1", methods=("lbs", "pbs", "snug_like", "ncs_like", "gaps")),
    *[TableSpec(f"gaps_heldout_{g}", f"GAPS against its own skinning, its loss's optimum and vbd on held-out motion and "
                f"shapes: the {g}", HELDOUT_METRICS, group="case",
                sweeps=(Sweep("gaps_heldout", (SEEDS, "method=gaps", f"garment={g}", ONE_THREAD)),
                        Sweep("gaps_heldout", ("method=lbs,gaps_optimum", f"garment={g}", ONE_THREAD))),
                methods=("lbs", "gaps_optimum", "gaps"), garments=(g,)) for g in ("tshirt", "dress", "skirt")],  # fmt: skip
    TableSpec("gaps_heldout_tshirt_anny", "gaps_heldout_tshirt on the full anny body",
              HELDOUT_METRICS, group="case",
              sweeps=(Sweep("gaps_heldout", (SEEDS, "method=gaps", "garment=tshirt", "body=anny", ONE_THREAD)),
                      Sweep("gaps_heldout", ("method=lbs,gaps_optimum", "garment=tshirt", "body=anny", ONE_THREAD))),
              methods=("lbs", "gaps_optimum", "gaps")),  # fmt: skip
    TableSpec("gaps_generalisation", "GAPS trained on named motions and on random motion against its untrained skinning "
              "and lbs on the held-out kick and on dance", ("eps_e", "eps_a", "eps_c", "vertex_error_mm", "energy_j"), group="scene",
              sweeps=(Sweep("gaps_generalisation", ("method=lbs", ONE_THREAD)), *untrained("gaps_generalisation", ("gaps",), ONE_THREAD),
                      Sweep("gaps_generalisation", ("method=gaps", ONE_THREAD)),
                      Sweep("gaps_generalisation", ("method=gaps", "method.name=gaps_random", "train.dataset=train_random_small", ONE_THREAD)),
                      Sweep("gaps_generalisation", ("method=pbs_style3d,pbs_half_dt", ONE_THREAD))),
              methods=("lbs", "gaps_untrained", "gaps", "gaps_random", "pbs_style3d", "pbs_half_dt")),  # fmt: skip
]
