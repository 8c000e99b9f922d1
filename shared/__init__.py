"""claychain shared: code shared by the stages.

The numba kernels run parallel loops on OpenMP threads. By default idle OpenMP threads
spin between loops; on a machine whose other cores are busy (two jobs on two cores)
they then steal the time of the serial work in between (a 2 000-point micro run took
45 s with spinning threads, 31 s without, the same as on one thread). They sleep
instead unless the user chose otherwise; the policy is read when OpenMP starts, so it
is set here, before any kernel runs.
"""

import os

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
