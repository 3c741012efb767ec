"""dtdyn's version: the one place it is written (pyproject.toml reads it, `dtdyn.__version__`
and the provenance of saved results and cached scheme files use it)."""

VERSION = "0.1.0"
