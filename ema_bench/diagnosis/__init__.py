"""Missing-physics workflow: does the fitted monitor model miss something, and what?

``features`` turns residuals into named statistics, ``envelopes`` gives their spread under
the fitted model plus sensor noise (bootstrap), ``stiction`` weighs out the stuck rotor's
path-dependent current, ``screening`` ranks library effects by how well their signatures
explain the residuals (a linearised score test), ``workflow`` fits single effects, pairs and
grown sets, ``verdict`` holds the rules that judge them (pure functions), ``report`` shows the
discrepancy shrink, ``blind`` scores the workflow on hidden cases, ``decoys`` makes the faults
of the acquisition chain among them.  See docs/diagnosis.md.
"""
