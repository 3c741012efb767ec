"""The private engine: input checks (validate), linear algebra (linalg), the scheme registry
(schemes), the time stepping (stepping), the C kernels and their compile cache (kernels,
cbuild), results and their files (result, result_io), errors, optional extras, atomic writes."""

#: nothing: the engine is private; `dtdyn` re-exports what users need from it (the errors and
#: warnings, Response, load_result, load_scheme, FileScheme, ground_acceleration_from)
__all__: list[str] = []
