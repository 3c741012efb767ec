/* stop.h: hand-written C, compiled as it is (dtdyn/_engine/csrc) */
#ifndef DTDYN_STOP_H
#define DTDYN_STOP_H
/*
 * Cooperative stop (Ctrl-C). The runtime runs a long call of this library in a worker thread;
 * on KeyboardInterrupt the main thread calls dtdyn_set_stop(1), and the loop returns
 * DTDYN_STOPPED at its next check (every block of samples: well under a second).
 */
#include "c_api.h" /* DTDYN_STOPPED */
static volatile int dtdyn_stop_flag = 0;

int dtdyn_set_stop(int value)
{
    dtdyn_stop_flag = value;
    return 0;
}
#endif /* DTDYN_STOP_H */
