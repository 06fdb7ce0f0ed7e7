"""The simulation log: one declaration of the logged arrays serves recording, saving, loading."""

from __future__ import annotations

import dataclasses
import re

import numpy as np

from geosyn.sim import SimResult
from geosyn.sim.log import LOG_FIELDS, allocate_rows, finish_rows


def _array_attributes() -> list[str]:
    return [f.name for f in dataclasses.fields(SimResult) if f.type in ("np.ndarray", np.ndarray)]


def test_field_table_is_the_results_arrays_in_order():
    assert [f.name for f in LOG_FIELDS] == _array_attributes()
    assert {f.source for f in LOG_FIELDS} == {"tick", "derived", "final"}


def test_docstring_states_each_fields_shape_and_unit():
    """The attribute docs of SimResult agree with the table (shape first, unit in [..])."""
    doc = SimResult.__doc__ or ""
    for f in LOG_FIELDS:
        line = re.search(rf"^\s+{f.name}: (.*)$", doc, flags=re.MULTILINE)
        assert line is not None, f"{f.name} is not documented"
        text = line.group(1)
        # the doc may continue on the next lines: take the whole paragraph of the field
        start = doc.index(line.group(0))
        nxt = re.search(r"^\s{8}\w+: ", doc[start + len(line.group(0)) :], flags=re.MULTILINE)
        para = doc[start : start + len(line.group(0)) + (nxt.start() if nxt else len(doc))]
        assert text.startswith("(" + ", ".join(f.shape) + (",)" if len(f.shape) == 1 else ")"))
        if f.unit:
            assert f"[{f.unit}]" in para, f"{f.name}: unit [{f.unit}] not in its doc"


def test_rows_are_allocated_from_the_table_and_finished_with_derived_fields():
    rows = allocate_rows(5, {"nq": 2, "nv": 2, "P": 1})
    tick = [f for f in LOG_FIELDS if f.source == "tick"]
    assert list(rows) == [f.name for f in tick]
    for f in tick:
        assert rows[f.name].dtype == f.dtype and rows[f.name].shape[0] == 5
    assert np.isnan(rows["q_ref"]).all() and (rows["iterations"] == -1).all()
    rows["q"][:3] = 1.0
    rows["q_ref"][:3] = 1.5
    rows["v"][:3] = 2.0
    rows["tau_applied"][:3] = 3.0
    out = finish_rows(rows, 3, 0.01)
    derived = [f.name for f in LOG_FIELDS if f.source == "derived"]
    assert set(out) == set(rows) | set(derived)
    assert all(len(a) == 3 for a in out.values())
    np.testing.assert_allclose(out["tracking_error"], 0.5)
    np.testing.assert_allclose(out["power"], 12.0)
    np.testing.assert_allclose(out["effort"], [0.18, 0.36, 0.54])
