"""Snapshots the results of every shipped scenario (under each dynamics its header names, both FMI versions of the
shipped models, `--step` 1 and 0.05 s) into one .npz, and compares two snapshots array by array.

    python tools/results_snapshot.py take before.npz      # on the commit before a structural change
    python tools/results_snapshot.py take after.npz       # after it
    python tools/results_snapshot.py compare before.npz after.npz

A structural change (code moved, split or renamed) must leave every array equal (`numpy.array_equal`, NaN equal to
NaN): the time series, the events, the warnings, the criticality record and the vehicles' tracks. Wall-clock
timing and file paths are left out.
"""

from __future__ import annotations

import json
import re
import sys

import numpy as np

WRITTEN_FOR = re.compile(r"^// Written for: (.+?) dynamics", re.M)
SKIPPING = re.compile(r"^// Written for: .+ dynamics, with --skip-unsupported", re.M)
DRIVER = re.compile(r"^// Written for: .+ dynamics, with --driver (\w+)", re.M)


def cases():
    """(name, dynamics, skip_unsupported, driver) of every shipped example, as its header says it is run."""
    from sdl_fmu import api

    for name, path in api.shipped_scenarios().items():
        text = path.read_text(encoding="utf-8")
        match = WRITTEN_FOR.search(text)
        if not match:
            continue
        driver = DRIVER.search(text)
        for dynamics in match.group(1).split(" and "):
            yield name, dynamics, SKIPPING.search(text) is not None, driver.group(1) if driver else "lane"


def _stable(summary: dict) -> dict:
    summary = dict(summary)
    for key in ("timing", "scenario", "vehicle"):
        summary.pop(key, None)
    return summary


def take(path: str) -> None:
    from sdl_fmu import api
    from sdl_fmu.fmu.cache import cached_fmus

    arrays = {}
    for name, dynamics, skip, driver in cases():
        for version, fmu in zip((2, 3), cached_fmus(dynamics, (2, 3))):
            for step in (1.0, 0.05):
                result = api.run(name, dynamics=dynamics, fmu=fmu, skip_unsupported=skip, step=step, driver=driver)
                key = f"{name}-{dynamics}-fmi{version}-step{step:g}"
                for header, values in result.arrays.items():
                    arrays[f"{key}/{header}"] = np.asarray(values)
                arrays[f"{key}/summary"] = np.array(json.dumps(_stable(result.summary), sort_keys=True, default=str))
                print(key, len(result.time), "samples", file=sys.stderr)
    np.savez_compressed(path, **arrays)


def compare(before: str, after: str) -> int:
    a, b = np.load(before), np.load(after)
    differ = sorted(set(a.files) ^ set(b.files))
    for key in sorted(set(a.files) & set(b.files)):
        x, y = a[key], b[key]
        equal_nan = x.dtype.kind == "f" and y.dtype.kind == "f"
        if x.shape != y.shape or not np.array_equal(x, y, equal_nan=equal_nan):
            differ.append(key)
    for key in differ:
        print("differs:", key)
    print(f"{len(set(a.files) & set(b.files))} arrays compared, {len(differ)} differ")
    return 1 if differ else 0


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "take":
        take(sys.argv[2])
    elif len(sys.argv) == 4 and sys.argv[1] == "compare":
        sys.exit(compare(sys.argv[2], sys.argv[3]))
    else:
        sys.exit(__doc__)
