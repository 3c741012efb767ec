/* flush_subnormals.h: hand-written C, compiled as it is (dtdyn/_engine/csrc) */
#ifndef DTDYN_FLUSH_SUBNORMALS_H
#define DTDYN_FLUSH_SUBNORMALS_H
/* Subnormal results flushed to zero, and subnormal operands read as zero, while a kernel runs
   (x86: MXCSR's FTZ and DAZ bits; AArch64: FPCR's FZ bit), the caller's mode restored on return.
   A response that decays or a wave entering a system at rest passes through the subnormal range
   (|x| < 2.2e-308) on its way to zero, where each operation can cost about a hundred cycles;
   flushed, such values become 0 (a flushed recursion may instead settle into a limit cycle just
   above 2.2e-308: the results change only near the underflow threshold). */
#if defined(__x86_64__) || defined(__i386__)
#include <xmmintrin.h>
static inline unsigned long long dtdyn_flush_on(void)
{
    const unsigned int mode = _mm_getcsr();
    _mm_setcsr(mode | 0x8040u);
    return mode;
}
static inline void dtdyn_flush_off(unsigned long long mode) { _mm_setcsr((unsigned int)mode); }
#elif defined(__aarch64__)
static inline unsigned long long dtdyn_flush_on(void)
{
    unsigned long long mode;
    __asm__ volatile("mrs %0, fpcr" : "=r"(mode));
    __asm__ volatile("msr fpcr, %0" : : "r"(mode | (1ull << 24)));
    return mode;
}
static inline void dtdyn_flush_off(unsigned long long mode)
{
    __asm__ volatile("msr fpcr, %0" : : "r"(mode));
}
#else
static inline unsigned long long dtdyn_flush_on(void) { return 0; }
static inline void dtdyn_flush_off(unsigned long long mode) { (void)mode; }
#endif

/* The loop a flushing entry point calls (name_run, called by dtdyn_name): not inlined into it,
   which keeps GCC's use of the loop's restrict parameters (inlined, the state-space loop of
   ss_response.c ran 7 % slower). */
#define DTDYN_LOOP __attribute__((noinline)) static
#endif /* DTDYN_FLUSH_SUBNORMALS_H */
