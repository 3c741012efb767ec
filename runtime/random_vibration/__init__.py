"""Random vibration: PSD tables, response PSDs of linear models and their spectral moments.

::

    from dtdyn.random_vibration import psd_table, random_response
    table = psd_table([(20, 0.01), (80, 0.04), (350, 0.04), (2000, 0.007)])   # (m/s^2)^2/Hz
    r = random_response(M, C, K, None, freqs_hz, ground_acceleration_psd=table)
    r.rms["a_abs"], r.info["rms_error_estimate"]

`psd_table` (`dtdyn.random_vibration._psd`) reads breakpoints as test specifications write them
(log-log between them, slopes in dB/octave); `random_response` and its `chain_`, `beam_` and
`shaft_` variants (`dtdyn.random_vibration._response`) give each output's cross-spectral matrix
S = H S_f H^H and its rms and spectral moments, integrated on a grid refined around every mode
with an error estimate. Fatigue: `rainflow_cycles` (ASTM E1049-85, in C) and its bin
matrices, `SNCurve` and Palmgren-Miner `miner_damage`, and the spectral damage of a stress PSD
(`spectral_damage`: narrow band, Wirsching-Light, Dirlik, Tovo-Benasciutti). Synthesis:
`random_time_history` (Gaussian records with a given PSD or cross-spectral matrix) and
`shock_time_history` (wavelets matched to a target SRS). Test specification: the vibration
response, extreme response and fatigue damage spectra (`vibration_response_spectrum`,
`extreme_response_spectrum`, `fatigue_damage_spectrum`) from a PSD or a record, and the PSD
whose FDS equals a given one (`fds_equivalent_psd`).
"""
from dtdyn.random_vibration._fatigue import (SNCurve, miner_damage, spectral_damage,
                                            spectral_damage_from_moments, spectral_moments)
from dtdyn.random_vibration._psd import PsdTable, psd_table
from dtdyn.random_vibration._rainflow import (CycleHistogram, Cycles, rainflow_cycles,
                                             turning_points)
from dtdyn.random_vibration._spectra import (VibrationSpectrum, extreme_response_spectrum,
                                            fatigue_damage_spectrum, fds_equivalent_psd,
                                            sdof_moments, vibration_response_spectrum)
from dtdyn.random_vibration._synthesis import (ShockTimeHistory, random_time_history,
                                              shock_time_history)
from dtdyn.random_vibration._response import (RandomResponse, beam_random_response,
                                             chain_random_response, random_response,
                                             shaft_random_response)

__all__ = ["psd_table", "PsdTable", "random_response", "chain_random_response",
           "beam_random_response", "shaft_random_response", "RandomResponse",
           "rainflow_cycles", "turning_points", "Cycles", "CycleHistogram",
           "SNCurve", "miner_damage", "spectral_damage", "spectral_damage_from_moments",
           "spectral_moments", "random_time_history", "shock_time_history", "ShockTimeHistory",
           "vibration_response_spectrum", "extreme_response_spectrum", "fatigue_damage_spectrum",
           "fds_equivalent_psd", "sdof_moments", "VibrationSpectrum"]
