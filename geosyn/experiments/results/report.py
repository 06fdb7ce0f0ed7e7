"""``geosyn report RUN_DIR``: regenerate a run's summaries and plots from its results.npz
and config (a sweep directory: `geosyn.experiments.results.report_sweep`)."""

from __future__ import annotations

import hashlib
import json
import zipfile
import zlib
from pathlib import Path

import numpy as np

from geosyn.experiments.config.loader import load_config
from geosyn.experiments.errors import ConfigError, ExperimentError, OutputNotWritable
from geosyn.experiments.procedures import PROCEDURES
from geosyn.experiments.results.report_sweep import report_sweep
from geosyn.experiments.results.summary import clean_summary, print_summary, write_summary

#: Largest results.npz `load_results` reads [bytes] (uncompressed size of its arrays).
MAX_RESULTS_BYTES = 4 << 30


def _rerun_hint(run_dir: Path) -> str:
    return (
        f"re-run it: geosyn run {str(run_dir / 'config.yaml')!r} --out NEW_DIR"
        " (the arrays cannot be rebuilt from the summaries)"
    )


def load_results(run_dir: Path) -> dict[str, np.ndarray]:
    """The arrays of ``run_dir/results.npz``, checked before use.

    The file must be an intact zip (every member's CRC is verified) of ``.npy`` arrays of
    plain numbers, booleans or text: no pickled objects (``allow_pickle=False``).

    Raises:
        ExperimentError: no results.npz, or a damaged one (truncated, bit-flipped, empty,
            pickled objects, too large); the message names the file and how to regenerate
            it.
    """
    run_dir = Path(run_dir)
    path = run_dir / "results.npz"
    if not path.is_file():
        raise ExperimentError(
            f"run_dir {str(run_dir)!r} has no results.npz; is it a run directory?"
        )

    def broken(reason: str) -> ExperimentError:
        return ExperimentError(f"{path} is damaged ({reason}); {_rerun_hint(run_dir)}")

    try:
        with zipfile.ZipFile(path) as archive:
            members = archive.infolist()
            total = sum(m.file_size for m in members)
            if total > MAX_RESULTS_BYTES:
                raise broken(f"its arrays take {total} bytes, more than {MAX_RESULTS_BYTES}")
            bad = archive.testzip()
            if bad is not None:
                raise broken(f"member {bad!r} fails its CRC check")
            if not members:
                raise broken("an empty archive")
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: np.array(data[k]) for k in data.files}
    except ExperimentError:
        raise
    except (zipfile.BadZipFile, zlib.error, EOFError, OSError, ValueError, KeyError) as err:
        reason = " ".join(str(err).split()) or type(err).__name__
        if "allow_pickle" in reason:
            reason = "it holds pickled Python objects, which are never loaded"
        raise broken(reason) from None
    for key, arr in arrays.items():
        if arr.dtype.kind not in "biufcUSM?":
            raise broken(f"array {key!r} has dtype {arr.dtype}, not numbers or text")
    problem = _shape_problem(arrays) or _digest_problem(run_dir, path)
    if problem:
        raise broken(problem)
    return arrays


def _shape_problem(arrays: dict[str, np.ndarray]) -> str | None:
    """Arrays of one logged run (``<run>__t``, ``<run>__q``, ...) disagree in length."""
    for key, t in arrays.items():
        if not key.endswith("__t") or t.ndim != 1:
            continue
        prefix = key[: -len("t")]
        for other, arr in arrays.items():
            if other.startswith(prefix) and arr.ndim >= 1 and arr.shape[0] != t.shape[0]:
                return f"array {other!r} has {arr.shape[0]} rows, {key!r} has {t.shape[0]}"
    return None


def _digest_problem(run_dir: Path, path: Path) -> str | None:
    """results.npz differs from the sha256 its run recorded in run.json (if it did)."""
    try:
        meta = json.loads((run_dir / "run.json").read_text())
    except (OSError, ValueError):
        return None  # no run.json (or an older run): nothing to compare with
    expected = meta.get("results_sha256") if isinstance(meta, dict) else None
    if not isinstance(expected, str):
        return None
    if hashlib.sha256(path.read_bytes()).hexdigest() != expected:
        return "its sha256 differs from the one run.json recorded: altered after the run"
    return None


def report(run_dir: str | Path, quiet: bool = False) -> dict[str, float]:
    """Regenerate summary.json, summary.md and the plots of a run directory (of a sweep
    directory: its tables and one plot per grid axis, `geosyn.experiments.results.report_sweep`;
    then the returned summary is empty).

    Raises:
        ExperimentError: not a run directory, a damaged results.npz, or results that do
            not match the config (each message names the file and how to regenerate it).
        ConfigError: its config.yaml is unreadable or no longer validates.
        OutputNotWritable: the summaries cannot be written.
    """
    run_dir = Path(run_dir)
    if (run_dir / "sweep.yaml").is_file():  # a sweep directory: its tables and axis plots
        report_sweep(run_dir, quiet=quiet)
        return {}
    if not (run_dir / "config.yaml").is_file():
        raise ExperimentError(
            f"run_dir {str(run_dir)!r} has no config.yaml; is it a run directory?"
        )
    results = load_results(run_dir)
    try:
        cfg, _ = load_config(run_dir / "config.yaml", allow_unused=True)
    except ConfigError as err:
        raise ConfigError(
            str(run_dir / "config.yaml"),
            err.field,
            f"{err.reason} (the run's saved config is damaged or from another version;"
            " re-run the experiment from its original config)",
        ) from None
    proc = PROCEDURES[cfg.kind]()
    params = proc.Params.model_validate(cfg.params)
    try:
        summary = clean_summary(proc.full_summary(cfg, params, results))
        if cfg.outputs.plots:
            proc.plot(cfg, params, results, run_dir)
    except OSError as err:  # a plot could not be written (read-only, disk full)
        raise OutputNotWritable(run_dir, err) from err
    except (KeyError, IndexError, ValueError, TypeError) as err:
        # results.npz of another experiment, or arrays of the wrong shape
        reason = " ".join(str(err).split())
        raise ExperimentError(
            f"{run_dir / 'results.npz'} does not match {run_dir / 'config.yaml'}"
            f" (kind {cfg.kind!r}: {type(err).__name__}: {reason[:200]}); it was written"
            f" by another experiment or altered; {_rerun_hint(run_dir)}"
        ) from None
    try:
        write_summary(run_dir, cfg.name, cfg.description, summary, proc.units)
    except OSError as err:
        raise OutputNotWritable(run_dir, err) from err
    if not quiet:
        print_summary(cfg.name, summary, proc.units)
    return summary


__all__ = ["MAX_RESULTS_BYTES", "load_results", "report"]
