"""Scenes: a model, its loads, a scheme, a time grid and the outputs wanted, read from TOML.

The file layout is documented in `dtdyn.app._scene.schema`; `parse` reads it into a `Scene`
(`matrices`: general-matrix models, `elements`: nonlinear elements), `run` simulates it and `io`
saves and plots the response; `steady` reads a ``[harmonic]`` table and runs, saves and plots
the periodic steady state.
"""
from dtdyn.app._scene.io import plot_response, save_results
from dtdyn.app._scene.parse import load_scene, scene_from_dict
from dtdyn.app._scene.run import check_stability, natural_frequencies, run_scene, scene_matrices
from dtdyn.app._scene.steady import plot_steady, run_steady, save_steady
from dtdyn.app._scene.schema import (BACKENDS, DEFAULT_SCENE, ELEMENT_KINDS, EXACT_MAX_DOF, FORMS,
                                    MODEL_KINDS, NONLINEAR_BACKENDS, QUANTITIES, SCHEMES, SWEEPS,
                                    Scene)

__all__ = ["Scene", "load_scene", "scene_from_dict", "run_scene", "save_results", "plot_response",
           "check_stability", "natural_frequencies", "scene_matrices", "SCHEMES", "FORMS",
           "SWEEPS", "BACKENDS", "QUANTITIES", "EXACT_MAX_DOF", "MODEL_KINDS", "ELEMENT_KINDS",
           "NONLINEAR_BACKENDS", "DEFAULT_SCENE", "run_steady", "save_steady", "plot_steady"]
