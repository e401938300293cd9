"""The vehicle test pack's duration per shipped model: wall and CPU time (`time.process_time`) of `api.verify`
for the whole pack, and of each manoeuvre, in one process (one core).

    python benchmarks/verify_pack.py [--dynamics simple advanced] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from provenance import stamp
from sdl_fmu import api


def main() -> int:
    arguments = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    arguments.add_argument("--dynamics", nargs="+", default=["simple", "advanced"])
    arguments.add_argument("--json")
    args = arguments.parse_args()
    report = {}
    for dynamics in args.dynamics:
        api.ego_fmu(dynamics)  # built (or found) in the cache before anything is timed
        with tempfile.TemporaryDirectory() as folder:
            wall, cpu = time.perf_counter(), time.process_time()
            result = api.verify(dynamics=dynamics, out=Path(folder) / "verify")
            wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        report[dynamics] = {"wall_s": round(wall, 2), "cpu_s": round(cpu, 2),
                            "manoeuvres_wall_s": {o.name: round(o.seconds, 2) for o in result.outcomes}}
        print(f"{dynamics}: pack {wall:.1f} s wall, {cpu:.1f} s CPU; "
              + ", ".join(f"{o.name} {o.seconds:.1f} s" for o in result.outcomes))
    if args.json:
        Path(args.json).write_text(json.dumps({"measured": stamp(), **report}, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
