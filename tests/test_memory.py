"""Memory in scenario length (a 200 000-line scenario runs in bounded memory; the benchmark's numbers are in
BENCHMARKS.md section 3). Each test measures two lengths of one generated scenario, so that what every run costs
whatever its length (imports, the FMU, caches) cancels in the difference, and compares the cost per added line with
limits set between what was measured before and after the change that bounded it (numbers in each test)."""

import gc
import json
import sys
import tracemalloc

import numpy as np

from sdl_fmu import api
from sdl_fmu.sdl import parse_text


def scenario_text(blocks: int) -> str:
    """6 lines per block, blocks 6 ft apart (short to run): an oncoming vehicle in the opposite lane, mu
    under the ego's wheels alternating 0.7 / 0.8, an RSA on the far shoulder, a 5 % brake for 0.02 s, two
    comment lines. Each block logs 6 events: spawn, despawn, 2 RSA, BRK on and off."""
    lines = ["English"]
    for k in range(blocks):
        d = 6 * (k + 1)
        lines += [f"{d},A,50,600,-6,{1 + k % 8}", f"{d},RSA,1,{7 if k % 2 == 0 else 8}", f"{d},RSA,-101,{2 + k % 3}",
                  f"{d},BRK,5,0,0.02", f"// block {k}", "//"]
    return "\n".join(lines) + "\n"


def traced_bytes(make) -> tuple[int, int, object]:
    """(bytes still allocated after make(), peak bytes during it, its value), by tracemalloc."""
    gc.collect()
    tracemalloc.start()
    try:
        value = make()
        gc.collect()
        current, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    return current, peak, value


def test_parsed_scenario_is_compact():
    # Measured (bytes per added line, 2 400 -> 4 800 lines): 219 with one dataclass instance (and its own
    # floats, tuples, Relative, ...) per event, 53 with slotted events sharing repeated field values (what
    # remains: per event line one small object and its line number, per block the distance and the BRK's
    # pedal; the parser's caches of shared values are full at both sizes). Limit between.
    small, _, _ = traced_bytes(lambda: parse_text(scenario_text(400)))
    large, _, _ = traced_bytes(lambda: parse_text(scenario_text(800)))
    per_line = (large - small) / (6 * 400)
    assert per_line < 110, f"the parsed scenario holds {per_line:.0f} B per line"


def test_a_run_keeps_no_object_per_line_or_event(tmp_path, simple_fmu, monkeypatch):
    """Python objects still allocated once a run has returned (sys.getallocatedblocks: no tracing, so the
    runs go at full speed), per added scenario line, the parsed scenario included."""
    import sdl_fmu.results.storage as storage

    # both lengths stream to files (a run that fits in one chunk keeps its samples in memory, bounded by
    # the chunk; a partly filled batch of events is up to EVENT_BATCH dicts): what is left grows per line
    monkeypatch.setattr(storage, "CHUNK_ROWS", 256)
    monkeypatch.setattr(storage, "EVENT_BATCH", 16)
    retained = {}
    for blocks in (5, 100, 200):  # the first only warms up (FMU, imports, caches)
        path = tmp_path / f"blocks_{blocks}.sdl"
        path.write_text(scenario_text(blocks))
        gc.collect()
        before = sys.getallocatedblocks()
        result = api.run(path, plot=False)
        gc.collect()
        retained[blocks] = sys.getallocatedblocks() - before
        assert len(result.events) == 6 * blocks + 1  # every event logged, and the ES
    per_line = (retained[200] - retained[100]) / 600
    # Measured: 14.0 objects per added line when each event was a dict in memory and each vehicle track
    # and surface section an object; 1.5 now, about what the parsed scenario itself holds (per event line
    # an event object and its line number, per block the distance and the BRK's pedal: 10 per 6 lines;
    # floats may come from the interpreter's free list and not count). A partly filled event batch (<= 16
    # dicts of ~8 objects) and allocator noise move it by < 0.3. Limit between.
    assert per_line < 4, f"{per_line:.1f} Python objects kept per scenario line"


def test_summary_json_streams_the_events(tmp_path):
    """Writing summary.json holds one event at a time, not the list and the whole text."""
    from sdl_fmu.results.files import summary, write_summary_json
    from sdl_fmu.results.record import RunRecord
    from sdl_fmu.results.storage import EventLog
    from sdl_fmu.sdl.events import DEFAULT_ROAD

    def result(events: int) -> RunRecord:
        log = EventLog()
        for k in range(events):
            log.append({"code": "A", "action": "spawn", "time_s": 0.1 * k, "distance": 8.8 * k, "speed": 88.0,
                        "lateral": -6.0, "vehicle": k + 1, "model": 1 + k % 8, "name": "car", "line": k + 2})
        return RunRecord("x.sdl", "English", "simple", 1, DEFAULT_ROAD, {}, [], log, 0, [], [],
                         final={"time_s": 1.0}, timing={"wall_s": 0.1})

    peaks = {}
    for events in (1000, 2000):
        run = result(events)
        path = tmp_path / f"summary_{events}.json"
        _, peaks[events], _ = traced_bytes(lambda: write_summary_json(run, path))
        assert path.read_text() == json.dumps(summary(run), indent=2) + "\n"  # byte for byte what it was
    # Measured: 2 190 B more peak per event when summary() built every event and json.dumps the whole
    # text; 4 now (one event at a time). Limit between.
    per_event = (peaks[2000] - peaks[1000]) / 1000
    assert per_event < 200, f"{per_event:.0f} B more peak memory per event writing summary.json"


def resident_bytes() -> int:
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * 4096 if sys.platform == "linux" else 0


def test_read_sample_pages_leave_resident_memory(monkeypatch):
    """The disk-backed sample tables: pages read (as the CSV writers do) and released leave the resident
    memory again, so writing a long run's files does not hold them all (the data stays in the file)."""
    from sdl_fmu.results.storage import ChunkedTable, release_pages

    rows, columns = 100_000, 25  # 20 MB
    table = ChunkedTable(columns)
    block = np.arange(10_000 * columns, dtype=float).reshape(10_000, columns)
    for k in range(rows // 10_000):
        table.extend(block + k)
    mapped = table.finish()
    before = resident_bytes()
    total = float(mapped[:, 3].sum())  # touches every page: the rows are interleaved
    touched = resident_bytes()
    release_pages(mapped[:, 3])
    released = resident_bytes()
    assert total == sum(float((block[:, 3] + k).sum()) for k in range(rows // 10_000))
    if sys.platform == "linux":
        size = rows * columns * 8
        # reading maps all 20 MB in; releasing drops them again (allowing 10 % for the process's other pages)
        assert touched - before > 0.9 * size and touched - released > 0.9 * size
    assert float(mapped[:, 3].sum()) == total  # still readable from the file after the release
