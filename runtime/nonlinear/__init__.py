"""Localized nonlinear elements (elements, expressions), the linear step of every scheme with the
element forces as inputs (linear_step), the nonlinear time histories (response; chain on the DT-
TMM) and their ODE reference (reference)."""
