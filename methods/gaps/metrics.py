"""The diagnostic GAPS reports beside the library's metrics (:meth:`methods.gaps.GAPS.diagnostics`): its own
training loss on its drape, which with a ``gaps_optimum`` run of the scene gives the report's ``loss_gap_closed``."""

from drapebench.metric_info import MetricInfo

METRICS = {
    "gaps_loss": MetricInfo("GAPS loss (J)", "J", "lower, down to its optimum's",
                            "GAPS's own training loss per frame (its weighted terms, k_ext at its cap)", own_loss=True),
}
