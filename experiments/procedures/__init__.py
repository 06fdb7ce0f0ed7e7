"""Built-in experiment procedures, registered by ``kind`` in `PROCEDURES`."""

from geosyn.experiments.procedures import (  # noqa: E402,F401  (registers)
    geodesic_vs_euclidean,
    pga_vs_pca,
    push_recovery,
    shaping,
    synergy_combinations,
    synergy_transport,
)
from geosyn.experiments.procedures.base import (
    PROCEDURES,
    NoParams,
    Procedure,
    RunContext,
    check_required,
    register,
)

__all__ = ["PROCEDURES", "NoParams", "Procedure", "RunContext", "check_required", "register"]
