"""Localized nonlinear elements (elements, expressions), the linear step of every scheme with the
element forces as inputs (linear_step), the nonlinear time histories (response; chain on the DT-
TMM) and their ODE reference (reference)."""

from dtdyn._engine.lazy import attach

__all__, __getattr__, __dir__ = attach(__name__, {
    "_chain": ["nonlinear_chain_response"],
    "_elements": ["BoucWen", "Cubic", "Gap", "Law", "Polynomial"],
    "_reference": ["check_reference", "reference_response"],
    "_response": ["nonlinear_mck_response"],
    "_harmonic_balance": ["HarmonicBalanceResult", "harmonic_balance",
                          "harmonic_balance_amplitude"],
    "_backbone": ["BackboneResult", "backbone"],
    "_stations": ["nonlinear_beam_response", "nonlinear_shaft_response"],
})
