"""The application: the dtdyn command (_cli), scenes (_scene/), batches (_batch/), load records
(_loads), the work-precision bench (_bench), the reference problems P1-P4 (_problems), the
derived equations shown to a user (_derivation) and the benchmarks' timing (_timing)."""

from dtdyn._engine.lazy import attach

__all__, __getattr__, __dir__ = attach(__name__, {
    "_problems": ["problem"],
    "_derivation": ["derivation"],
    # the benchmarks' timing (benchmarks/*.py)
    "_timing": ["Timing", "measure", "interleaved", "pin_blas", "SPREAD"],
    # from the home modules, where `dtdyn` puts its keyword-checked functions
    "_scene.schema": ["Scene"],
    "_scene.parse": ["load_scene", "scene_from_dict"],
    "_scene.run": ["run_scene"],
    "_scene.steady": ["run_steady"],
    "_batch.run": ["run_batch"],
    "_batch.store": ["ResumeMismatchError"],
    "_batch.montecarlo": ["monte_carlo_summary"],
    # the `dtdyn` command's entry point, main(argv) -> exit code
    "_cli": ["main"],
    # the reducers a batch takes (run_batch(..., reduce=[Rms(start=1.0), ...]))
    "_batch.reducers": ["Spectrum", "Rms", "Welch", "Damage"],
})
