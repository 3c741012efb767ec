"""The private engine: input checks (validate), linear algebra (linalg), the scheme registry
(schemes), the time stepping (stepping), the C kernels and their compile cache (kernels,
cbuild), results and their files (result, result_io), errors, optional extras, atomic writes."""
