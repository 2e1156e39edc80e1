"""Clean-data bias of the monitor: polish from the truth on noise-free reference traces.

For each instance (the suite's: the four paper cases and s00 .. s19; or, with a number N, the
paper cases and N random ones), CMA-ES starts at the true faults
with small steps and minimises the fitness against clean reference traces (no noise, no ADC;
:func:`ema_bench.monitor_bias.clean_bias`).  Where it ends is the monitor's own best fit: its
distance from the truth, in % of each fault's range, is the model-form bias that no solver can
remove.  Target (issue 10): < 0.3 % for every
fault.

    python benchmarks/clean_bias.py > benchmarks/results/clean_bias_suite.txt   # the suite
    python benchmarks/clean_bias.py 20 > bias.txt
    python benchmarks/clean_bias.py --model-version 4 \
        > benchmarks/results/clean_bias_suite_v4.txt   # model version 4's monitor
"""

import sys

import numpy as np

from ema_bench.faults import CASES, random_faults
from ema_bench.monitor_bias import clean_bias
from ema_bench.params import model_params
from ema_bench.suites.v1 import instance_faults, instance_names

if __name__ == "__main__":
    args = sys.argv[1:]
    version = "3"
    if args[:1] == ["--model-version"]:
        version, args = args[1], args[2:]
    params = model_params(version)
    if args:
        cases = {k: c.x for k, c in CASES.items()}
        for i in range(int(args[0])):
            cases[f"seeded{i}"] = random_faults(np.random.SeedSequence(1234, spawn_key=(i,)))
    else:
        cases = {n: instance_faults(n) for n in instance_names()}
    worst = np.zeros(4)
    if version != "3":
        print(f"monitor: model version {version}")
    print(f"{'instance':10s} {'Na %':>7} {'Fst %':>7} {'BLK %':>7} {'Gprop %':>7}  f(truth)  "
          "f(best)")
    for name, x in cases.items():
        r = clean_bias(x, params=params)
        err, f0, f1 = 100.0 * r["range_error"], r["fitness_truth"], r["fitness_best"]
        worst = np.maximum(worst, np.abs(err))
        print(f"{name:10s} " + " ".join(f"{e:+7.3f}" for e in err) + f"  {f0:.3g}  {f1:.3g}",
              flush=True)
    print(f"{'worst |.|':10s} " + " ".join(f"{e:7.3f}" for e in worst))
