"""Building a run's programs from its config: the env stack, the devices and processes they run on, the seeds'
keys and sweep members, and compiling them (XLA options, the compile and program caches)."""
