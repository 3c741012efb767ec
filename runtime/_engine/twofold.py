"""Error-free transformations: a sum or a product of two doubles as an unevaluated pair
hi + lo that equals it exactly (double-double arithmetic), element-wise on arrays.

Used where a residual must be summed beyond the working precision: the refined solves and
mode refinement of long beams (their K has cond ~ N^4), and the beam time step's refinement.
T. J. Dekker, "A floating-point technique for extending the available precision", Numer.
Math. 18 (1971); D. E. Knuth, TAOCP vol. 2, 4.2.2.
"""
from __future__ import annotations

#: Veltkamp's splitter 2^27 + 1: a = hi + lo, each of 26 bits, so their products are exact
SPLITTER = 134217729.0


def split(a):
    """(hi, lo) with a = hi + lo exactly, each half of 26 significant bits."""
    c = SPLITTER * a
    hi = c - (c - a)
    return hi, a - hi


def two_prod(a, b, a_parts=None, b_parts=None):
    """(p, e) with a b = p + e exactly, p = fl(a b) (Dekker's product; NumPy has no fma).
    ``a_parts``, ``b_parts``: `split` of a or b when already at hand."""
    p = a * b
    ah, al = split(a) if a_parts is None else a_parts
    bh, bl = split(b) if b_parts is None else b_parts
    return p, ((ah * bh - p) + ah * bl + al * bh) + al * bl


def two_sum(a, b):
    """(s, e) with a + b = s + e exactly, s = fl(a + b) (Knuth)."""
    s = a + b
    bb = s - a
    return s, (a - (s - bb)) + (b - bb)


def add_product(hi, lo, a, b):
    """The double-double (hi, lo) + a b."""
    p, ep = two_prod(a, b)
    s, e = two_sum(hi, p)
    return s, lo + (e + ep)
