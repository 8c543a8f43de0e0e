"""
Relay shifts: batteries, a spare, a second base station
=======================================================

Relays fly on batteries (5 Wh here: about 55 s each). When one's energy left is what getting home needs plus its
reserve, it flies home and leaves the network; a spare waiting at the depot launches early enough to be beside it
by then and takes its place on the route. The inspector's route ends at ``"any"`` of two base stations, and the
network hands over to the better one (by the route's rate, with a margin and a dwell time)::

    python examples/relay_shifts.py            # the whole 150 s mission, writes runs/example_relay_shifts/
"""

import os
from pathlib import Path

import aerorelay as ar

SCENARIOS = Path("scenarios") if Path("scenarios").is_dir() else Path("../scenarios")  # run from the repository or examples/

DURATION = float(os.environ.get("AERORELAY_EXAMPLE_DURATION", "150"))
OUT = os.environ.get("AERORELAY_EXAMPLE_OUT", "runs/example_relay_shifts")

sc = ar.load_scenario(SCENARIOS / "relay_shifts.toml", set={"sim.duration_s": DURATION})
result = ar.simulate(sc)
m = result.metrics
print(f"network: C_min {m['c_min'] / 1e6:.2f} Mbit/s, mean C {m['c_mean'] / 1e6:.2f} Mbit/s, handovers {m['handovers']}, "
      f"closest two vehicles {m['separation_min_m']:.1f} m, unsafe: {m['unsafe']}")
print("  served by: " + ", ".join(f"{b} {share:.0%}" for b, share in m["routes"]["inspector"]["served_fraction"].items()))
for name, r in m["relays"].items():
    if r.get("standby_only"):
        print(f"  {name}: waited the whole flight")
        continue
    events = [f"{what} {r[key]:.1f} s" for what, key in (("launched", "launched_at_s"), ("took over", "took_over_at_s"),
                                                        ("home at", "went_home_at_s"), ("landed", "landed_at_s")) if key in r]
    print(f"  {name}: {', '.join(events) or 'flew the whole flight'}; {r['energy_kJ']:.1f} kJ")
ts = result.timeseries
print("  base station serving at the end:", ts["inspector.base_station"].iloc[-1])
result.save(os.path.join(OUT, "run"), figures=False)
print(f"wrote {OUT}")
