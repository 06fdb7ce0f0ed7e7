"""Fuzz: >= 50 hostile command lines and ``geosyn report`` inputs, in-process: exit 2, one
line, no traceback, nothing left behind (or a run directory left unchanged), bounded time."""

from __future__ import annotations

import os
import random
import shutil
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from fuzzing import assert_clean_cli_error, files_under, run_cli

SRC = "planar2_geodesic_vs_euclidean"
FAST = ["--set", "outputs.plots=false", "--set", "params.steps=60", "--no-progress"]

_rng = random.Random(5)
_names = [
    "n" + "".join(_rng.choice("abcxyz_-./") for _ in range(_rng.randrange(1, 12))) for _ in range(4)
]

#: (case id, argv after ``geosyn``, the command in the error line, a phrase of the line)
RUN_CASES: list[tuple[str, list[str], str, str]] = [
    *[(f"unknown_name_{i}", ["run", n], "run", "ConfigError") for i, n in enumerate(_names)],
    ("missing_yaml", ["run", "no/such/file.yaml"], "run", "no such file"),
    ("directory_as_config", ["run", "."], "run", "ConfigError"),
    ("set_no_equals", ["run", SRC, "--set", "simulation.duration"], "run", "--set"),
    ("set_empty_key", ["run", SRC, "--set", "=1"], "run", "--set"),
    ("set_empty_part", ["run", SRC, "--set", "simulation..duration=1"], "run", "--set"),
    ("set_index_out_of_range", ["run", SRC, "--set", "controllers.7.kp=1"], "run", "out of range"),
    ("set_not_an_index", ["run", SRC, "--set", "controllers.x.kp=1"], "run", "not an index"),
    ("set_through_scalar", ["run", SRC, "--set", "name.first=1"], "run", "not a section"),
    ("set_deep_value", ["run", SRC, "--set", "x=" + "[" * 100 + "]" * 100], "run", "nested"),
    ("set_bad_date", ["run", SRC, "--set", "x=2001-13-45"], "run", "invalid YAML value"),
    ("set_unknown_field", ["run", SRC, "--set", "simulation.durration=1"], "run", "durration"),
    ("set_wrong_type", ["run", SRC, "--set", "simulation.duration=[1, 2]"], "run", "duration"),
    ("set_bomb_duration", ["run", SRC, "--set", "simulation.duration=2e4"], "run", "MAX_TICKS"),
    ("set_nan", ["run", SRC, "--set", "simulation.duration=.nan"], "run", "duration"),
    ("set_complex", ["run", SRC, "--set", "controllers.0.kp=1+2j"], "run", "kp"),
    ("unknown_command", ["frobnicate"], "", ""),
    ("unknown_option", ["run", SRC, "--frobnicate"], "", ""),
    ("no_experiment", ["run"], "", ""),
    ("seeds_text", ["sweep", SRC, "--seeds", "abc"], "", ""),
    ("seeds_zero", ["sweep", SRC, "--seeds", "0"], "sweep", "seeds"),
    ("seeds_negative", ["sweep", SRC, "--seeds", "-3"], "sweep", "seeds"),
    ("seeds_million", ["sweep", SRC, "--seeds", "1000000"], "sweep", "--max-runs"),
    ("workers_zero", ["sweep", SRC, "--workers", "0"], "sweep", "workers"),
    ("workers_huge", ["sweep", SRC, "--workers", "100000"], "sweep", "workers"),
    ("workers_text", ["sweep", SRC, "--workers", "many"], "", ""),
    ("max_runs_zero", ["sweep", SRC, "--max-runs", "0"], "sweep", "max_runs"),
    ("grid_no_equals", ["sweep", SRC, "--grid", "controllers.0.kp"], "sweep", "--grid"),
    ("grid_empty_value", ["sweep", SRC, "--grid", "controllers.0.kp=1,"], "sweep", "--grid"),
    ("grid_twice", ["sweep", SRC, "--grid", "a=1", "--grid", "a=2"], "sweep", "twice"),
    ("grid_bad_value", ["sweep", SRC, "--grid", "controllers.0.kp=100,abc"], "sweep", "grid point"),
    (
        "grid_10k_points",
        [
            "sweep",
            SRC,
            "--grid",
            "seed=" + ",".join(map(str, range(100))),
            "--grid",
            "controllers.0.kp=" + ",".join(map(str, range(1, 101))),
        ],
        "sweep",
        "10000 runs",
    ),
    *[
        (f"ray_malformed_{i}", ["sweep", SRC, "--ray", a], "sweep", "--ray")
        for i, a in enumerate(["nohost", "host:99999", "http://h:1", "h :1", ":1"])
    ],
]


@pytest.mark.parametrize(
    "argv, command, phrase", [c[1:] for c in RUN_CASES], ids=[c[0] for c in RUN_CASES]
)
def test_hostile_command_line(tmp_path, monkeypatch, argv, command, phrase):
    monkeypatch.chdir(tmp_path)
    full = [*argv, "--out", str(tmp_path / "out")] if command in ("run", "sweep") else argv
    code, out, err = run_cli(full)
    if command == "":  # argparse usage errors: exit 2 with its usage text, no traceback
        assert code == 2 and "Traceback" not in err and "error:" in err, err
    else:
        line = assert_clean_cli_error(code, out, err, command=command)
        assert phrase in line, line
    assert files_under(tmp_path) == []


def test_out_pointing_at_a_file(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    target = tmp_path / "results.txt"
    target.write_text("keep")
    for extra in ([], ["--force"]):
        code, out, err = run_cli(["run", SRC, "--out", str(target), *FAST, *extra])
        assert "RunDirectoryExists" in assert_clean_cli_error(code, out, err, command="run")
        code, out, err = run_cli(["sweep", SRC, "--out", str(target), *FAST])
        assert "RunDirectoryExists" in assert_clean_cli_error(code, out, err, command="sweep")
    assert target.read_text() == "keep" and files_under(tmp_path) == ["results.txt"]


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("base") / "run"
    code, _, err = run_cli(["run", SRC, "--out", str(out), *FAST])
    assert code == 0, err
    return out


def _npz(d: Path) -> Path:
    return d / "results.npz"


def _flip(d: Path, where: float) -> None:
    data = bytearray(_npz(d).read_bytes())
    data[int(len(data) * where)] ^= 0xFF
    _npz(d).write_bytes(bytes(data))


def _resave(d: Path, change: Callable[[dict], dict]) -> None:
    with np.load(_npz(d)) as r:
        arrays = {k: r[k] for k in r.files}
    np.savez(_npz(d), **change(arrays))


def _other_kind(d: Path) -> None:
    text = (d / "config.yaml").read_text().replace("kind: geodesic_vs_euclidean", "kind: tracking")
    (d / "config.yaml").write_text(text)


#: (case id, how to damage a copy of a good run directory, a phrase of the error line)
REPORT_CASES: list[tuple[str, Callable[[Path], object], str]] = [
    ("truncated_npz_half", lambda d: _npz(d).write_bytes(_npz(d).read_bytes()[:-2000]), "damaged"),
    ("truncated_npz_head", lambda d: _npz(d).write_bytes(_npz(d).read_bytes()[:100]), "damaged"),
    ("empty_npz", lambda d: _npz(d).write_bytes(b""), "damaged"),
    ("bitflip_npz_20", lambda d: _flip(d, 0.2), "damaged"),
    ("bitflip_npz_50", lambda d: _flip(d, 0.5), "damaged"),
    ("bitflip_npz_80", lambda d: _flip(d, 0.8), "damaged"),
    ("pickled_npz", lambda d: np.savez(_npz(d), x=np.array([{"a": 1}], dtype=object)), "pickled"),
    ("empty_zip", lambda d: zipfile.ZipFile(_npz(d), "w").close(), "empty archive"),
    ("text_as_npz", lambda d: _npz(d).write_text("not a zip"), "damaged"),
    ("npz_is_directory", lambda d: (_npz(d).unlink(), _npz(d).mkdir()), "no results.npz"),
    ("missing_npz", lambda d: _npz(d).unlink(), "no results.npz"),
    ("missing_config", lambda d: (d / "config.yaml").unlink(), "no config.yaml"),
    ("binary_config", lambda d: (d / "config.yaml").write_bytes(os.urandom(300)), "config.yaml"),
    ("empty_config", lambda d: (d / "config.yaml").write_text(""), "config.yaml"),
    ("config_other_kind", _other_kind, "config.yaml"),
    ("arrays_of_another_run", lambda d: _resave(d, lambda a: {"foo": np.zeros(3)}), "damaged"),
    (
        "arrays_cut_short",
        lambda d: _resave(d, lambda a: {k: v[:5] if v.ndim else v for k, v in a.items()}),
        "damaged",
    ),
    (
        "arrays_cut_without_run_json",
        lambda d: (
            (d / "run.json").unlink(),
            _resave(d, lambda a: {k: (v[:-1] if k.endswith("__q") else v) for k, v in a.items()}),
        ),
        "rows",
    ),
    (
        "arrays_renamed_without_run_json",
        lambda d: (
            (d / "run.json").unlink(),
            _resave(d, lambda a: {k.replace("tau", "tua"): v for k, v in a.items()}),
        ),
        "does not match",
    ),
]


@pytest.mark.parametrize(
    "damage, phrase", [c[1:] for c in REPORT_CASES], ids=[c[0] for c in REPORT_CASES]
)
def test_report_on_a_damaged_run_directory(tmp_path, run_dir, damage, phrase):
    d = tmp_path / "run"
    shutil.copytree(run_dir, d)
    damage(d)
    before = {p: p.stat().st_mtime_ns for p in d.rglob("*")}
    code, out, err = run_cli(["report", str(d)])
    line = assert_clean_cli_error(code, out, err, command="report")
    assert phrase in line, line
    assert {p: p.stat().st_mtime_ns for p in d.rglob("*")} == before  # nothing rewritten


@pytest.mark.parametrize("target", ["missing", "a_file", "empty_dir"])
def test_report_on_something_else(tmp_path, target):
    path = tmp_path / target
    if target == "a_file":
        path.write_text("x")
    elif target == "empty_dir":
        path.mkdir()
    code, out, err = run_cli(["report", str(path)])
    assert "is it a run directory" in assert_clean_cli_error(code, out, err, command="report")


def test_report_of_the_intact_run_succeeds(tmp_path, run_dir):
    d = tmp_path / "run"
    shutil.copytree(run_dir, d)
    code, out, err = run_cli(["report", str(d)])
    assert code == 0, err


def test_there_are_at_least_50_cases():
    assert len(RUN_CASES) + 1 + len(REPORT_CASES) + 3 >= 50
