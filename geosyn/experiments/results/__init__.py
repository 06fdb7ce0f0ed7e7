"""What a run leaves: `summary` (``summary.json``/``.md``), `report` (``geosyn report``),
`report_sweep` and `aggregate` (sweep tables and plots), `data` (per-run CSV, tidy
tables), `plots`, `run_video` (a video of every motion of a run)."""

__all__: list[str] = []
