"""Built-in experiment procedures, registered by ``kind`` in `PROCEDURES`."""

from geosyn.experiments.procedures import (  # noqa: E402,F401  (registers)
    geodesic_vs_euclidean,
    human_synergies,
    perception_reach,
    pga_vs_pca,
    pick_and_place,
    push_recovery,
    shaping,
    synergy_combinations,
    synergy_sequence,
    synergy_transport,
    tracking,
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
