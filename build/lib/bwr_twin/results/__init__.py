"""Results: records and online metrics of a run, run directories, figures."""
