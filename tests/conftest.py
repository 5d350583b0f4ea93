"""Every test process (each xdist worker) starts with one thread for torch and one for the world.

A test that runs a policy beside the world would otherwise start torch's pool and numba's on every core; the two
OpenMP runtimes' workers spin after each parallel region and take the cores from each other: a 40x4 cell of six maps
with B's policy took 56 s with both pools on two cores beside another job, 1.5 s on one thread each (the apps set
the counts the same way, searchrl/threads.py). A test that needs other counts sets them and puts these back.
"""

from searchrl.threads import use_threads

use_threads(1)
