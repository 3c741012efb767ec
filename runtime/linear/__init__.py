"""Linear time histories and discrete models: DT-TMM chains (chain), assembled matrices (mck), the
exact response (exact), discrete state space (state_space, discrete_model, discretize), the
Laplace-domain TMM (tmm) and the schemes' stability (stability)."""

from dtdyn._engine.lazy import attach

__all__, __getattr__, __dir__ = attach(__name__, {
    "_chain": ["Chain", "chain_matrices", "rayleigh_chain_damping", "chain_response"],
    "_beam": ["Beam", "PointMass", "Support", "beam_frequencies", "beam_matrices", "beam_response"],
    "_beam_frequency": ["beam_frequency_response", "beam_modes"],
    "_discrete_model": ["DiscreteModel"],
    "_discretize": ["discretize", "first_order_form"],
    "_exact": ["exact_response"],
    "_frequencies": ["chain_frequencies", "chain_poles"],
    "_mck": ["Matrices", "mck_response"],
    "_shaft": ["Branch", "ContinuousShaft", "Shaft", "shaft_frequencies", "shaft_matrices",
              "shaft_response"],
    "_shaft_frequency": ["shaft_frequency_response", "shaft_modes"],
    "_solver": ["Solver"],
    "_stability": ["Stability", "critical_omega_dt", "stability"],
    "_state_space": ["discrete_state_space", "newmark_ss", "state_space_response"],
    "_tmm": ["chain_frequency_response"],
})
