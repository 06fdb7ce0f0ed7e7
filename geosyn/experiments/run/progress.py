"""Progress bars of runs and sweeps (rich, transient: gone when the work is done)."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator

from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn


@contextlib.contextmanager
def progress_bars(enabled: bool) -> Iterator[Callable[[str, int], Callable[[], None]]]:
    """A factory of progress bars: ``factory(description, total)`` gives ``advance()``.

    With ``enabled`` False the bars draw nothing (sweep workers, ``quiet`` runs).
    """
    if not enabled:
        yield lambda description, total: lambda: None
        return
    with Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        TextColumn("{task.completed}/{task.total}"),
        TimeElapsedColumn(),
        transient=True,
    ) as bar:

        def factory(description: str, total: int) -> Callable[[], None]:
            task = bar.add_task(description, total=total)
            return lambda: bar.advance(task)

        yield factory


__all__ = ["progress_bars"]
