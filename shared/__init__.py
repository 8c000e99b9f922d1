"""claychain shared: code shared by the stages.

The numba kernels run parallel loops on OpenMP threads. By default idle OpenMP threads
spin between loops; on a machine whose other cores are busy (two jobs on two cores)
they then steal the time of the serial work in between (a 2 000-point micro run took
45 s with spinning threads, 31 s without, the same as on one thread). They sleep
instead unless the user chose otherwise; the policy is read when OpenMP starts, so it
is set here, before any kernel runs. numba itself prefers TBB to OpenMP wherever a TBB
library is installed (Debian's ``yade`` package brings one), and the micro runs of the
test suite then took two to three times longer: OpenMP is put first unless the user
chose a threading layer. Both go through the environment, which numba reads when it is
imported (and again before compiling when it changed), so that importing ``shared`` does
not import numba: the workflow's configuration helpers stay light.
"""

import os
import sys
from typing import Any

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

if not {"NUMBA_THREADING_LAYER", "NUMBA_THREADING_LAYER_PRIORITY"} & set(os.environ):
    os.environ["NUMBA_THREADING_LAYER_PRIORITY"] = "omp workqueue tbb"
    if "numba.core.config" in sys.modules:  # numba came first: set its loaded value too
        numba_config: Any = sys.modules["numba.core.config"]  # a module of untyped attributes
        numba_config.THREADING_LAYER_PRIORITY = ["omp", "workqueue", "tbb"]
