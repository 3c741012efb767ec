"""Modal models (model: poles and residues), modal digital filters (filters), their frequency-
domain errors (filter_errors) and shock response spectra (srs)."""

from dtdyn._engine.lazy import attach

__all__, __getattr__, __dir__ = attach(__name__, {
    "_filter_errors": ["continuous_frequency_response", "discrete_frequency_response", "ramp_bias",
                      "truncation_error"],
    "_filters": ["modal_filter_response", "to_sos"],
    "_model": ["ModalModel", "from_poles_residues", "modal_model"],
    "_modes": ["Modes", "mck_modes"],
    "_spectrum": ["ResponseSpectrum", "response_spectrum"],
    "_srs": ["SRS", "load_record", "sdof_response", "shock_response_spectrum"],
})
