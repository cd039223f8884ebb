"""How vsj compiles its numerical kernels (one place for the numba flags).

``kernel`` compiles a function once and caches it on disk; ``inline`` does the
same for small helpers that are inlined into their callers.

``error_model="numpy"`` makes a division by zero give inf or NaN instead of
raising: the engine checks for non-finite states and reports them with time
and state, and the raising paths (with the reference counting they drag into
every hot loop) cost up to a microsecond per evaluation.
"""

from numba import njit

kernel = njit(cache=True, error_model="numpy")
inline = njit(cache=True, error_model="numpy", inline="always")
parallel = njit(cache=True, error_model="numpy", parallel=True)
#: For allocation-free inner loops that receive every array from their caller
#: (the time-stepper's loop): compiled without reference counting, which in a
#: branchy loop over many arrays costs a call and an atomic add per array use.
loop = njit(cache=True, error_model="numpy", _nrt=False)
