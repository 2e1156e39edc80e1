"""Missing-physics workflow: does the fitted monitor model miss something, and what?

``features`` turns residuals into named statistics, ``envelopes`` gives their spread under
the fitted model plus sensor noise (bootstrap), ``screening`` ranks library effects by how
well their signatures explain the residuals (a linearised score test), ``workflow`` fits the
candidates and decides, ``report`` shows the gap shrink, ``blind`` scores the workflow on
hidden cases.
"""
