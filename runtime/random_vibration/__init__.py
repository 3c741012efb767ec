"""Random vibration: PSD tables, response PSDs of linear models and their spectral moments.

::

    from dtdyn.random_vibration import psd_table, random_response
    table = psd_table([(20, 0.01), (80, 0.04), (350, 0.04), (2000, 0.007)])   # (m/s^2)^2/Hz
    r = random_response(M, C, K, None, freqs_hz, ground_acceleration_psd=table)
    r.rms["a_abs"], r.info["rms_error_estimate"]

`psd_table` (`dtdyn.random_vibration.psd`) reads breakpoints as test specifications write them
(log-log between them, slopes in dB/octave); `random_response` and its `chain_`, `beam_` and
`shaft_` variants (`dtdyn.random_vibration.response`) give each output's cross-spectral matrix
S = H S_f H^H and its rms and spectral moments, integrated on a grid refined around every mode
with an error estimate.
"""
from dtdyn.random_vibration.psd import PsdTable, psd_table
from dtdyn.random_vibration.response import (RandomResponse, beam_random_response,
                                             chain_random_response, random_response,
                                             shaft_random_response)

__all__ = ["psd_table", "PsdTable", "random_response", "chain_random_response",
           "beam_random_response", "shaft_random_response", "RandomResponse"]
