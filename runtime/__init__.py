"""dtdyn: discrete-time structural dynamics, derived with SymPy and run as generated NumPy and C.

Everything a user needs is importable from here::

    import dtdyn as dd
    r = dd.chain_response(mass, stiffness, damping, force, dt, force_dofs=[14])

The package is organized in rooms: `dtdyn.linear` (chains, M/C/K time histories, exact and
state-space discretizations, TMM, stability), `dtdyn.modal` (modal models, modal digital filters,
their errors, the shock response spectrum), `dtdyn.nonlinear` (localized elements, the nonlinear
time histories and their ODE reference), `dtdyn.app` (scenes, the `dtdyn` command, benchmarks,
the reference problems) and the private engine `dtdyn._engine`. The generated kernels live in
`dtdyn.generated`, the SymPy derivations in `dtdyn.derive` (needs the ``[derive]`` extra).
"""
from dtdyn._engine.errors import (DtdynAccuracyWarning, DtdynCacheError, DtdynFallbackWarning,
                                  DtdynStabilityWarning, DtdynStepStabilityError,
                                  DtdynUnstableError, NewtonError, SingularMassError,
                                  SRSSamplingWarning)
from dtdyn._engine.ground import ground_acceleration_from
from dtdyn._engine.result import Response
from dtdyn._engine.result_io import load_result
from dtdyn._engine.version import VERSION
from dtdyn._engine.scheme_files import FileScheme, load_scheme
from dtdyn.app._batch import monte_carlo_summary, run_batch
from dtdyn.app._problems import problem
from dtdyn.app._scene import Scene, load_scene, run_scene, scene_from_dict
from dtdyn.linear._chain import Chain, chain_matrices, rayleigh_chain_damping, chain_response
from dtdyn.linear._beam import (Beam, PointMass, Support, beam_frequencies, beam_matrices,
                               beam_response)
from dtdyn.linear._beam_frequency import beam_frequency_response, beam_modes
from dtdyn.linear._discrete_model import DiscreteModel
from dtdyn.linear._discretize import discretize, first_order_form
from dtdyn.linear._exact import exact_response
from dtdyn.linear._frequencies import chain_frequencies, chain_poles
from dtdyn.linear._mck import Matrices, mck_response
from dtdyn.linear._shaft import (Branch, ContinuousShaft, Shaft, shaft_frequencies, shaft_matrices,
                                shaft_response)
from dtdyn.linear._shaft_frequency import shaft_frequency_response, shaft_modes
from dtdyn.linear._solver import Solver
from dtdyn.linear._stability import Stability, critical_omega_dt, stability
from dtdyn.linear._state_space import discrete_state_space, newmark_ss, state_space_response
from dtdyn.linear._tmm import chain_frequency_response
from dtdyn.modal._filter_errors import (continuous_frequency_response, discrete_frequency_response,
                                       ramp_bias, truncation_error)
from dtdyn.modal._filters import modal_filter_response, to_sos
from dtdyn.modal._model import ModalModel, from_poles_residues, modal_model
from dtdyn.modal._modes import Modes, mck_modes
from dtdyn.modal._spectrum import ResponseSpectrum, response_spectrum
from dtdyn.modal._srs import SRS, load_record, sdof_response, shock_response_spectrum
from dtdyn.nonlinear._chain import nonlinear_chain_response
from dtdyn.nonlinear._elements import BoucWen, Cubic, Gap, Law, Polynomial
from dtdyn.nonlinear._reference import check_reference, reference_response
from dtdyn.nonlinear._response import nonlinear_mck_response
from dtdyn.nonlinear._harmonic_balance import (HarmonicBalanceResult, harmonic_balance,
                                              harmonic_balance_amplitude)
from dtdyn.nonlinear._backbone import BackboneResult, backbone
from dtdyn.nonlinear._stations import nonlinear_beam_response, nonlinear_shaft_response
from dtdyn.random_vibration import (CycleHistogram, Cycles, RandomResponse, SNCurve,
                                    beam_random_response, chain_random_response, miner_damage,
                                    psd_table, rainflow_cycles, random_response,
                                    shaft_random_response, spectral_damage,
                                    spectral_damage_from_moments, spectral_moments, turning_points,
                                    random_time_history, shock_time_history, ShockTimeHistory,
                                    VibrationSpectrum, extreme_response_spectrum,
                                    fatigue_damage_spectrum, fds_equivalent_psd, sdof_moments,
                                    vibration_response_spectrum)
from dtdyn.app._derivation import derivation

__version__ = VERSION

__all__ = [
    # linear time histories and discrete models
    "chain_response", "chain_matrices", "rayleigh_chain_damping", "Beam", "PointMass", "Support",
    "Matrices", "Chain", "Solver",
    "beam_matrices", "beam_frequencies", "beam_response", "beam_modes",
    "beam_frequency_response", "mck_response", "exact_response",
    "newmark_ss", "discrete_state_space", "state_space_response",
    "discretize", "first_order_form", "DiscreteModel",
    "chain_frequency_response", "chain_frequencies", "chain_poles", "stability",
    "critical_omega_dt",
    "Stability", "load_scheme", "FileScheme", "derivation",
    # torsional shafts and trees
    "Shaft", "Branch", "ContinuousShaft", "shaft_response", "shaft_matrices",
    "shaft_frequencies", "shaft_modes", "shaft_frequency_response",
    # modal
    "mck_modes", "Modes", "modal_model", "from_poles_residues", "ModalModel",
    "modal_filter_response", "to_sos",
    "discrete_frequency_response", "continuous_frequency_response", "ramp_bias",
    "truncation_error", "shock_response_spectrum", "sdof_response", "SRS", "load_record",
    "response_spectrum", "ResponseSpectrum",
    # nonlinear
    "nonlinear_mck_response", "nonlinear_chain_response", "nonlinear_shaft_response",
    "nonlinear_beam_response", "reference_response", "check_reference",
    "harmonic_balance", "harmonic_balance_amplitude", "HarmonicBalanceResult", "backbone",
    "BackboneResult",
    "Cubic", "Polynomial", "Gap", "Law", "BoucWen",
    # random vibration
    "psd_table", "random_response", "chain_random_response", "beam_random_response",
    "shaft_random_response", "RandomResponse",
    "rainflow_cycles", "turning_points", "Cycles", "CycleHistogram", "SNCurve", "miner_damage",
    "spectral_damage", "spectral_damage_from_moments", "spectral_moments",
    "random_time_history", "shock_time_history", "ShockTimeHistory",
    "vibration_response_spectrum", "extreme_response_spectrum", "fatigue_damage_spectrum",
    "fds_equivalent_psd", "sdof_moments", "VibrationSpectrum",
    # scenes, results, reference problems
    "ground_acceleration_from", "Scene", "load_scene", "scene_from_dict", "run_scene", "Response",
    "load_result",
    "run_batch", "monte_carlo_summary",
    "problem",
    # errors and warnings
    "NewtonError", "DtdynStepStabilityError", "DtdynUnstableError", "SingularMassError",
    "DtdynAccuracyWarning",
    "DtdynStabilityWarning", "DtdynFallbackWarning", "SRSSamplingWarning", "DtdynCacheError",
    "__version__",
]


def _check_keywords():
    """Every public function and class checks its keywords (`dtdyn._engine.public`); the
    checked function replaces the plain one in its home module too (one object, one name)."""
    import sys
    from dtdyn._engine.public import public
    for name in __all__:
        obj = globals()[name]
        if isinstance(obj, type) and (issubclass(obj, BaseException)
                                      or obj.__init__ is object.__init__) or not callable(obj):
            continue                   # errors, and tuples built by __new__ (no keywords here)
        if getattr(obj, "__dtdyn_public__", False) or \
                getattr(getattr(obj, "__init__", None), "__dtdyn_public__", False):
            continue
        checked = public(obj)
        globals()[name] = checked
        if not isinstance(obj, type):
            setattr(sys.modules[obj.__module__], name, checked)


_check_keywords()


def _deprecated():
    """Old name -> (new name, the object it now means)."""
    def p(name):
        return lambda *args, **kw: problem(name, **({"n_samples": args[0]} if args else kw))

    def old_modes(M, K, C=None, *, count=None, influence=None):
        return mck_modes(M, C, K, count=count, influence=influence)

    return {"simulate_chain": ("chain_response", chain_response),
            "simulate_mck": ("mck_response", mck_response),
            "simulate_beam": ("beam_response", beam_response),
            "simulate_shaft": ("shaft_response", shaft_response),
            "nonlinear_response": ("nonlinear_mck_response", nonlinear_mck_response),
            "frequency_response": ("chain_frequency_response", chain_frequency_response),
            "undamped_poles": ("chain_frequencies", chain_frequencies),
            "modes": ("mck_modes(M, C, K) (note the argument order)", old_modes),
            "p1": ('problem("P1")', p("P1")), "p2": ('problem("P2")', p("P2")),
            "p3": ('problem("P3")', p("P3")), "p4": ('problem("P4", n_samples=...)', p("P4"))}


def __getattr__(name):
    """The names of the previous release, for one more release, with a DeprecationWarning."""
    old = _deprecated().get(name)
    if old is None:
        raise AttributeError(f"module 'dtdyn' has no attribute {name!r}")
    import warnings
    warnings.warn(f"dtdyn.{name} is now dtdyn.{old[0]}; the old name will be removed in the "
                  "next release", DeprecationWarning, stacklevel=2)
    return old[1]
