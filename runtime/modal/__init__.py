"""Modal models (model: poles and residues), modal digital filters (filters), their frequency-
domain errors (filter_errors) and shock response spectra (srs)."""
