/*
 * Cooperative stop (Ctrl-C). The runtime runs a long call of this library in a worker thread;
 * on KeyboardInterrupt the main thread calls dtdyn_set_stop(1), and the loop returns
 * DTDYN_STOPPED at its next check (every block of samples: well under a second).
 */
#define DTDYN_STOPPED 5
static volatile int dtdyn_stop_flag = 0;

int dtdyn_set_stop(int value)
{
    dtdyn_stop_flag = value;
    return 0;
}
