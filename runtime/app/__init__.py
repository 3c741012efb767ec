"""The application: the dtdyn command (cli), scenes (scene/), load records (loads), the work-
precision benchmarks (bench) and the reference problems P1-P4 (problems)."""
