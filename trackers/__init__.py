"""The baseline trackers of degradation campaigns.

Each module registers a tracker factory with
:func:`ema_bench.prognostics.tracking.register_tracker` and is named in ema-bench's own
``[project.entry-points."ema_bench.trackers"]`` table, exactly as a third-party tracker package
would be.  Run one with ``ema_bench.prognostics.track_run.track_campaign(dir, name, out)`` or
``ema-bench campaign track DIR --tracker NAME --out DIR2``; list them with
``ema-bench campaign track --list``.

* ``refit-trend`` (:mod:`.refit_trend`): fit every inspection, extrapolate each fault's trend;
* ``kalman`` (:mod:`.kalman`): a local-linear-trend Kalman filter over the fitted estimates;
* ``particle`` (:mod:`.particle`): a particle filter weighted directly on the traces.
* ``fleet-bayes`` (:mod:`.fleet_bayes`): the unit's degradation-law parameters updated from
  its fits, the fleet's published laws as priors; the laws run forward.

Shared conventions (:mod:`._common`): faults tracked as *damage* (share of range towards the
threshold); RUL distributions from Monte Carlo paths to the thresholds; one replacement rule;
``Gprop`` never fails.
"""
