"""Property-based fuzzing (Hypothesis): the settings profiles and the `fuzz` marker.

Every test in tests/fuzz runs twice over the same properties:

- in CI (plain ``pytest``): profile ``ci``, a fixed seed (``derandomize=True``) and a bounded number
  of examples per test (``DTDYN_FUZZ_CI_EXAMPLES``, default 40), the whole folder in well under a
  minute;
- on request (``pytest -m fuzz tests/fuzz``): the tests marked ``fuzz``, profile ``fuzz``, random
  seeds and ``DTDYN_FUZZ_EXAMPLES`` examples per test (default 2000). The marked tests are skipped
  unless ``-m`` names the marker.
"""
import os

import pytest
from hypothesis import HealthCheck, settings

_SLOW_OK = [HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much]

#: the first call of an entry point compiles its C kernel (seconds): no per-example deadline; a
#: hang is caught by the examples' own size limits (every input is small)
settings.register_profile(
    "ci", max_examples=int(os.environ.get("DTDYN_FUZZ_CI_EXAMPLES", "40")), derandomize=True,
    deadline=None, print_blob=True, suppress_health_check=_SLOW_OK, database=None)
settings.register_profile(
    "fuzz", max_examples=int(os.environ.get("DTDYN_FUZZ_EXAMPLES", "2000")), derandomize=False,
    deadline=None, print_blob=True, suppress_health_check=_SLOW_OK)


def pytest_collection_modifyitems(config, items):
    wanted = "fuzz" in (config.option.markexpr or "")
    skip = pytest.mark.skip(reason="the long Hypothesis run: pytest -m fuzz tests/fuzz")
    for item in items:
        if item.get_closest_marker("fuzz") is not None and not wanted:
            item.add_marker(skip)
