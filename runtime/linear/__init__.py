"""Linear time histories and discrete models: DT-TMM chains (chain), assembled matrices (mck), the
exact response (exact), discrete state space (state_space, discrete_model, discretize), the
Laplace-domain TMM (tmm) and the schemes' stability (stability)."""

from dtdyn._engine.lazy import attach

# `stability` and `discretize` are also modules of this package (the attribute is the module):
# use dtdyn.stability and dtdyn.discretize until the modules are private
__all__, __getattr__, __dir__ = attach(__name__, {
    "chain": ["Chain", "chain_matrices", "rayleigh_chain_damping", "chain_response"],
    "beam": ["Beam", "PointMass", "Support", "beam_frequencies", "beam_matrices", "beam_response"],
    "beam_frequency": ["beam_frequency_response", "beam_modes"],
    "discrete_model": ["DiscreteModel"],
    "discretize": ["first_order_form"],
    "exact": ["exact_response"],
    "frequencies": ["chain_frequencies", "chain_poles"],
    "mck": ["Matrices", "mck_response"],
    "shaft": ["Branch", "ContinuousShaft", "Shaft", "shaft_frequencies", "shaft_matrices",
              "shaft_response"],
    "shaft_frequency": ["shaft_frequency_response", "shaft_modes"],
    "solver": ["Solver"],
    "stability": ["Stability", "critical_omega_dt"],
    "state_space": ["discrete_state_space", "newmark_ss", "state_space_response"],
    "tmm": ["chain_frequency_response"],
})
