"""The hard cases (issue "Hard cases stay numerically stable"): one suite that tries them all.

Every module here is marked ``hard`` and runs in the default test run. The
shared references (a float64 horizon bake, a float64 ray caster over the
displaced mesh, the GPU path's channel weights) live in :mod:`tests.hard._ref`.
"""
