"""Fuzz: >= 100 malformed experiment files (encodings, nesting, sizes, resource bombs,
wrong types, unknown keys, broken syntax), each through ``geosyn run`` in-process: exit 2,
one line naming the file, no traceback, no run directory, bounded time. The resource
bombs also run in a subprocess under a memory limit (they must be refused, not allocated).
"""

from __future__ import annotations

import codecs
import copy
import os
import random
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
import yaml
from fuzzing import assert_clean_cli_error, files_under, run_cli

BASE = {
    "name": "fuzz",
    "kind": "tracking",
    "robot": {"name": "planar2"},
    "reference": {"type": "log", "q_start": [0.2, 0.3], "goal": [0.8, 0.9], "duration": 0.5},
    "controllers": [{"type": "computed_torque", "kp": 400.0, "kd": 40.0}],
    "disturbances": [{"type": "torque_noise", "std": 0.01}],
    "simulation": {"duration": 0.3, "control_dt": 0.002},
    "params": {"threshold": 0.01},
}


def _dump(data: object) -> bytes:
    return yaml.safe_dump(data, sort_keys=False).encode()


def _set(path: str, value: object, data: dict | None = None) -> dict:
    data = copy.deepcopy(BASE if data is None else data)
    *head, last = path.split(".")
    node: object = data
    for part in head:
        node = node[int(part)] if isinstance(node, list) else node.setdefault(part, {})  # type: ignore[index,union-attr]
    if isinstance(node, list):
        node[int(last)] = value
    else:
        node[last] = value  # type: ignore[index]
    return data


def _nested(depth: int, kind: str) -> str:
    if kind == "flow":
        return "robot: {name: planar2}\nx: " + "[" * depth + "]" * depth + "\n"
    if kind == "map":
        return "robot: {name: planar2}\nx: " + "{a: " * depth + "1" + "}" * depth + "\n"
    lines = ["robot: {name: planar2}", "x:"]
    lines += ["  " * (i + 1) + "a:" for i in range(depth)]
    return "\n".join(lines) + " 1\n"


BILLION_LAUGHS = (
    "robot: {name: planar2}\n"
    + "\n".join(
        [f"l{0}: &l0 [x, x, x, x, x, x, x, x, x, x]"]
        + [f"l{i}: &l{i} [" + ", ".join([f"*l{i - 1}"] * 10) + "]" for i in range(1, 9)]
    )
    + "\n"
)


def _encoding_cases(rng: random.Random) -> list[tuple[str, bytes, str]]:
    valid_missing_robot = _dump({k: v for k, v in BASE.items() if k != "robot"})
    cases = [
        ("binary_random", bytes(rng.randrange(256) for _ in range(4096)), ""),
        ("binary_elf", b"\x7fELF\x02\x01\x01" + bytes(200), ""),
        ("binary_png", b"\x89PNG\r\n\x1a\n" + bytes(rng.randrange(256) for _ in range(500)), ""),
        ("nul_in_text", _dump(BASE).replace(b"fuzz", b"fu\x00zz"), "NUL"),
        ("utf16_le_bom_missing_robot", valid_missing_robot.decode().encode("utf-16"), "robot"),
        (
            "utf16_be_bom_missing_robot",
            codecs.BOM_UTF16_BE + valid_missing_robot.decode().encode("utf-16-be"),
            "robot",
        ),
        ("utf16_no_bom", _dump(BASE).decode().encode("utf-16-le"), ""),
        ("utf32_bom_missing_robot", valid_missing_robot.decode().encode("utf-32"), "robot"),
        ("latin1_name", _dump(BASE).replace(b"fuzz", "fuzzé".encode("latin-1")), "UTF-8"),
        ("truncated_utf8", _dump(BASE) + "é".encode()[:1], "UTF-8"),
        ("empty", b"", "mapping"),
        ("only_bom", codecs.BOM_UTF8, "mapping"),
    ]
    for i in range(8):  # random bytes with a valid-looking YAML start
        junk = bytes(rng.randrange(128, 256) for _ in range(rng.randrange(1, 64)))
        cases.append((f"junk_tail_{i}", b"name: x\nrobot: {name: planar2}\n" + junk, ""))
    return cases


def _structure_cases() -> list[tuple[str, bytes, str]]:
    cases = []
    for depth in (40, 200, 5000):
        for kind in ("flow", "map", "block"):
            d = min(depth, 400) if kind == "block" else depth  # 5000 indented lines: 25 MB
            cases.append((f"depth_{kind}_{d}", _nested(d, kind).encode(), "nested"))
    cases.append(("billion_laughs", BILLION_LAUGHS.encode(), "values"))
    big = "robot: {name: planar2}\ncomment: '" + "x" * (256 << 10) + "'\n"
    cases.append(("over_256_KiB", big.encode(), "bytes"))
    many = "robot: {name: planar2}\nx: [" + ",".join(["1"] * 110_000) + "]\n"
    cases.append(("110k_values", many.encode(), "values"))
    cases.append(("date_out_of_range", b"robot: {name: planar2}\nwhen: 2001-13-45\n", "YAML"))
    cases.append(("tabs", b"robot:\n\tname: planar2\n", "YAML"))
    cases.append(("unclosed_flow", b"robot: {name: planar2\n", "YAML"))
    cases.append(("python_tag", b"robot: !!python/object:os.system [ls]\n", "YAML"))
    cases.append(("top_level_list", b"- robot\n- planar2\n", "mapping"))
    cases.append(("top_level_scalar", b"42\n", "mapping"))
    cases.append(("duplicate_anchor_merge", b"a: &a {x: 1}\nrobot: {<<: *a}\n", ""))
    return cases


#: Resource bombs: (name, config, phrase); refused before anything is allocated.
BOMBS = [
    ("duration_2e4", _set("simulation.duration", 2e4), "GEOSYN_MAX_TICKS"),
    ("duration_1e9", _set("simulation.duration", 1e9), "GEOSYN_MAX_TICKS"),
    ("duration_1e300", _set("simulation.duration", 1e300), "GEOSYN_MAX_TICKS"),
    ("control_dt_1e-9", _set("simulation.control_dt", 1e-9), "GEOSYN_MAX_TICKS"),
    ("reference_duration_1e7", _set("reference.duration", 1e7), "GEOSYN_MAX_TICKS"),
    (
        "latency_1e9_ticks",
        _set("disturbances", [{"type": "latency", "ticks": 10**9}]),
        "longer than the run",
    ),
    (
        "latency_1e6_s",
        _set("disturbances", [{"type": "latency", "seconds": 1e6}]),
        "longer than the run",
    ),
    ("substeps_1e9", _set("simulation.substeps", 10**9), "simulation.substeps"),
    ("duration_inf", _set("simulation.duration", float("inf")), "simulation.duration"),
    ("duration_nan", _set("simulation.duration", float("nan")), "simulation.duration"),
]

#: Scalar fields of BASE and values that can never be valid there.
SCALARS = [
    "simulation.duration",
    "simulation.control_dt",
    "reference.duration",
    "controllers.0.kp",
    "controllers.0.kd",
    "disturbances.0.std",
    "params.threshold",
]
BAD_SCALARS = ["abc", {"x": 1}, [[1.0]], "1+2j", -1.0, None, float("nan")]
VECTORS = ["reference.q_start", "reference.goal"]
BAD_VECTORS = [[0.1], [0.1, 0.2, 0.3], "zero", [["a"], 1], [float("inf"), 0.0], {"q": 1}]
SECTIONS = ["", "reference", "controllers.0", "disturbances.0", "simulation", "params", "robot"]


def _type_cases(rng: random.Random) -> list[tuple[str, bytes, str]]:
    cases = []
    for field in SCALARS:
        for bad in rng.sample(BAD_SCALARS, 4):
            name = f"{field}={bad!r}"[:60]
            if bad == -1.0 and field == "disturbances.0.std":
                bad = -5.0
            cases.append((name, _dump(_set(field, bad)), field))
    for field in VECTORS:
        for bad in BAD_VECTORS:
            cases.append((f"{field}={bad!r}"[:60], _dump(_set(field, bad)), field))
    for section in SECTIONS:
        key = rng.choice(["foo", "kpp", "durration", "tpye", "x_y"])
        path = f"{section}.{key}" if section else key
        cases.append((f"unknown_{path}", _dump(_set(path, 1)), key))
    return cases


def _syntax_cases(rng: random.Random) -> list[tuple[str, bytes, str]]:
    text = _dump(BASE).decode()
    cases = []
    for i in range(10):  # an unmatched bracket at a random line start: never valid YAML
        lines = text.splitlines()
        k = rng.randrange(len(lines))
        lines[k] = lines[k] + " [" if ":" in lines[k] else "[" + lines[k]
        cases.append((f"bracket_{i}", ("\n".join(lines) + "\n").encode(), ""))
    return cases


RNG = random.Random(15)
CASES = (
    _encoding_cases(RNG)
    + _structure_cases()
    + [(n, _dump(c), p) for n, c, p in BOMBS]
    + _type_cases(RNG)
    + _syntax_cases(RNG)
)


def test_there_are_at_least_100_cases():
    assert len(CASES) >= 100
    assert len({name for name, _, _ in CASES}) == len(CASES)


def test_the_base_config_is_valid():
    from geosyn.experiments.config.loader import validate_config

    validate_config(BASE)


@pytest.mark.parametrize("name, content, phrase", CASES, ids=[c[0] for c in CASES])
def test_malformed_config(tmp_path, monkeypatch, name, content, phrase):
    monkeypatch.chdir(tmp_path)  # a default run directory would appear here
    path = tmp_path / "bad.yaml"
    path.write_bytes(content)
    code, out, err = run_cli(["run", str(path), "--no-progress"])
    line = assert_clean_cli_error(code, out, err, command="run")
    assert "ConfigError: bad.yaml: " in line, line
    assert phrase in line, line
    assert files_under(tmp_path) == ["bad.yaml"]


def test_utf16_config_with_bom_is_read():
    """A config saved as UTF-16 (with its byte-order mark) reads like the UTF-8 one."""
    from geosyn.experiments.config.loader import read_yaml

    for encoding in ("utf-16", "utf-32", "utf-8-sig"):
        path = Path(os.environ.get("TMPDIR", "/tmp")) / f"geosyn-fuzz-{os.getpid()}.yaml"
        try:
            path.write_bytes(_dump(BASE).decode().encode(encoding))
            assert read_yaml(path) == BASE
        finally:
            path.unlink(missing_ok=True)


_BOMB_SCRIPT = textwrap.dedent(
    """
    import resource, sys, yaml
    from pathlib import Path
    from geosyn.experiments.cli import main
    import geosyn.experiments.procedures, geosyn.robots, geosyn.sim  # imports before the limit

    def vm_bytes():
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmSize:"):
                return int(line.split()[1]) * 1024
    limit = vm_bytes() + (1 << 30)  # 1 GiB above what the imports took
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    codes = []
    for path in sys.argv[1:]:
        codes.append(main(["run", path, "--no-progress", "--out", path + ".run"]))
    print(" ".join(map(str, codes)))
    """
)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_resource_bombs_are_refused_under_a_memory_limit(tmp_path):
    paths = []
    for name, cfg, _ in BOMBS:
        path = tmp_path / f"{name}.yaml"
        path.write_bytes(_dump(cfg))
        paths.append(str(path))
    done = subprocess.run(
        [sys.executable, "-c", _BOMB_SCRIPT, *paths],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.split() == ["2"] * len(BOMBS), done.stderr[-3000:]
    assert "Traceback" not in done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(Path(p).name for p in paths)
