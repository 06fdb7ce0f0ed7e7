"""Procedures that build their own simulation refuse ``robot.plant: file`` by name
instead of silently simulating geosyn's model (the file plant would be ignored)."""

from __future__ import annotations

import pytest

from geosyn.core import GeosynError
from geosyn.experiments import load_config


@pytest.mark.parametrize("kind", ["perception_reach", "human_synergies"])
def test_plant_file_is_refused_naming_the_field(kind: str) -> None:
    with pytest.raises(GeosynError, match=r"robot\.plant: must be 'model'"):
        load_config(kind, ["robot.plant=file"])
    load_config(kind, ["robot.plant=model"])  # the default is accepted
