/* sorted_loads.h: hand-written C, compiled as it is (dtdyn/_engine/csrc) */
#ifndef DTDYN_SORTED_LOADS_H
#define DTDYN_SORTED_LOADS_H
#include <stdlib.h>
/* The loaded indices of a kernel call ascending and once each (the chain's and the tree's stable
   sweeps redo the loaded stations after a terms loop that skips the force row). */
static int dtdyn_compare_long(const void *a, const void *b)
{
    const long x = *(const long *)a, y = *(const long *)b;
    return (x > y) - (x < y);
}

/* out = the n indices of loaded, sorted, repeats dropped; returns how many remain */
static long dtdyn_sorted_loads(long n, const long *loaded, long *out)
{
    long j, m = 0;
    for (j = 0; j < n; ++j)
        out[j] = loaded[j];
    qsort(out, (size_t)n, sizeof(long), dtdyn_compare_long);
    for (j = 0; j < n; ++j)
        if (m == 0 || out[j] != out[m - 1])
            out[m++] = out[j];
    return m;
}
#endif /* DTDYN_SORTED_LOADS_H */
