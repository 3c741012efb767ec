"""dtdyn runtime: what users import (NumPy, SciPy, CasADi; no SymPy or jinja2).

The main entry points are importable from here; each module loads on first use:

    from dtdyn.runtime import simulate_chain, simulate_mck, exact_response
"""
from importlib import import_module

_EXPORTS = {
    "simulate_chain": "chain", "chain_matrices": "chain",
    "simulate_mck": "mck",
    "exact_response": "exact",
    "newmark_ss": "state_space", "discrete_state_space": "state_space",
    "state_space_response": "state_space",
    "discretize": "discretize", "to_dlti": "discretize", "to_control": "discretize",
    "modal_model": "modal", "from_poles_residues": "modal",
    "modal_filter_response": "modal_filters",
    "shock_response_spectrum": "srs",
    "nonlinear_response": "nonlinear", "NewtonError": "nonlinear",
    "nonlinear_chain_response": "nonlinear_chain",
    "Cubic": "elements", "Polynomial": "elements", "Gap": "elements", "Law": "elements",
    "BoucWen": "elements",
    "reference_response": "nl_reference",
    "load_scene": "scene", "run_scene": "scene",
    "Response": "result",
}
__all__ = sorted(_EXPORTS)


def __getattr__(name):
    if name in _EXPORTS:
        return getattr(import_module(f"{__name__}.{_EXPORTS[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
