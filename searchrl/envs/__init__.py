"""Environment layers over the batched world: an SB3 VecEnv (parameter sharing), a PettingZoo ParallelEnv and
a single-agent gymnasium Env."""
