"""Every exception and warning dtdyn raises of its own, in one place (all re-exported by
`dtdyn`)."""

__all__ = ["NewtonError", "DtdynStepStabilityError", "DtdynUnstableError", "DtdynStabilityWarning",
           "DtdynAccuracyWarning", "SingularMassError", "SRSSamplingWarning",
           "DtdynFallbackWarning", "DtdynCacheError", "DtdynKernelError"]


class NewtonError(RuntimeError):
    """The per-step Newton iteration failed (not converged, singular Jacobian or non-finite)."""


class DtdynStepStabilityError(ValueError):
    """The elements' tangent stiffness is beyond the method's stability limit at this step."""


class DtdynUnstableError(ValueError):
    """The scheme is unstable at this dt for the model's highest mode (or a discrete model's
    recursion grows): the run would return growing garbage, so it does not start."""


class DtdynStabilityWarning(RuntimeWarning):
    """The scheme is unstable at this dt for some mode of the model."""


class DtdynAccuracyWarning(RuntimeWarning):
    """A result whose estimated error is large (e.g. the plain DT-TMM sweep on a long chain)."""


class SingularMassError(ValueError):
    """M is singular in a way `exact_response` cannot reduce (see its Notes)."""


class SRSSamplingWarning(RuntimeWarning):
    """The sampling limits the accuracy of the spectrum at the highest frequencies."""


class DtdynFallbackWarning(RuntimeWarning):
    """The C backend is unavailable and the NumPy implementation is used instead."""


class DtdynCacheError(RuntimeError):
    """A compiled library in the cache failed its checks (incomplete ELF file, missing entry
    points or the stamp of another cache key) again after it was removed and rebuilt once."""


class DtdynKernelError(RuntimeError):
    """A C kernel refused or failed a call (a broken contract between the runtime and the C
    code, never a user error): ``kernel``, its return code ``code`` and what it means."""

    def __init__(self, kernel: str, code: int, detail: str = ""):
        from dtdyn.generated import c_api  # the codes, from the one spec (dtdyn.derive.c_api)
        self.kernel, self.code = kernel, code
        meaning = {c_api.ERR_WORK: "its work array is too short (n_work below its rows times N); "
                                   "nothing was written",
                   c_api.ERR_FORM: "the scheme has no such form"}.get(code, "unknown code")
        super().__init__(f"C kernel {kernel} returned {code}: {meaning}"
                         + (f" ({detail})" if detail else ""))
