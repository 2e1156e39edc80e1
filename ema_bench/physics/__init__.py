"""Physics blocks of the EMA, one module per block of the block diagram.

``command`` -> ``ace`` -> ``bldc`` (power drive electronics + motor) -> ``mechanics``
(reducer, backlash, friction, end stops) <- ``load`` (hinge moment); ``sensors`` close the loop
and record the outputs.  Every block is a small pure function compiled with numba so the
reference and monitor integrators (``ema_bench.reference``, ``ema_bench.monitor``) can call
them in their hot loops.
"""
