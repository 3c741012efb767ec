"""Stability of every scheme: writes docs/stability.md and docs/stability.png from
`dtdyn stability --plot docs/stability.png` (the amplification matrices derived from each
scheme's relations, zeta = 0), so the page shows what the command prints at this version.

Usage: python benchmarks/stability_table.py
"""
from __future__ import annotations

import contextlib
import io
import pathlib

from dtdyn.app._cli import main

DOCS = pathlib.Path(__file__).resolve().parents[1] / "docs"
NOTES = (
    "Critical Omega of the conditionally stable Newmark schemes equals 1/sqrt(gamma/2 - beta): 2, "
    "2.449, 2.828, 3.464 (tests/symbolic/test_stability.py). Average acceleration keeps rho = 1 "
    "with period elongation Omega^2/12 (symbolic series); Houbolt and Park tend to 0, "
    "generalized-alpha to rho_inf, HHT to (1 + alpha)/(1 - alpha). Beyond Omega of a few units the "
    "principal pair of the strongly dissipative schemes becomes hard to identify (Park's "
    "elongation curve), where those modes are damped out anyway.\n")


def table(plot: str | None = None) -> str:
    """What `dtdyn stability [--plot PLOT]` prints."""
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(["stability"] + (["--plot", plot] if plot else []))
    if code:
        raise SystemExit(f"dtdyn stability failed with exit code {code}")
    return buf.getvalue()


if __name__ == "__main__":
    with contextlib.chdir(DOCS.parent):
        out = table("docs/stability.png")
    print(out, end="")
    (DOCS / "stability.md").write_text(
        "# Stability of every scheme\n\n"
        "Output of `dtdyn stability --plot docs/stability.png` (amplification matrices derived "
        "from each scheme's relations; zeta = 0), written by "
        "`python benchmarks/stability_table.py`:"
        "\n\n```\n" + out + "```\n\n"
        "![spectral radius, period elongation, algorithmic damping](stability.png)\n\n" + NOTES)
