"""What a run leaves: summaries, reports, tables, plots, videos."""
