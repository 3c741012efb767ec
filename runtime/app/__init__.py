"""The application: the dtdyn command (cli), scenes (scene/), load records (loads), the work-
precision benchmarks (bench) and the reference problems P1-P4 (problems)."""

from dtdyn._engine.lazy import attach

# `derivation` is also a module of this package (the attribute is the module): use
# dtdyn.derivation until the module is private
__all__, __getattr__, __dir__ = attach(__name__, {
    "problems": ["problem"],
    # from the home modules, where `dtdyn` puts its keyword-checked functions
    "scene.schema": ["Scene"],
    "scene.parse": ["load_scene", "scene_from_dict"],
    "scene.run": ["run_scene"],
    "batch.run": ["run_batch"],
    "batch.montecarlo": ["monte_carlo_summary"],
})
