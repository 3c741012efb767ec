"""Linear time histories and discrete models: DT-TMM chains (chain), assembled matrices (mck), the
exact response (exact), discrete state space (state_space, discrete_model, discretize), the
Laplace-domain TMM (tmm) and the schemes' stability (stability)."""
