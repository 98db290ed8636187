"""Tools that measure the pipeline (benchmarks): `python -m pipeline.tools.<name>`."""
