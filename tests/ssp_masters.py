"""The SSP masters as docs/export.md runs them: each master's recipe is read from that page (the code block of its
section) and run as written, in a subprocess of its own: libcosim prints the FMI Library's debug lines on standard
output (the results are read from the line that starts with MARKER), and a master that aborts takes only that
process."""

import json
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np

DOCS = Path(__file__).resolve().parents[1] / "docs" / "export.md"
MASTERS = ("libcosim", "ecos", "fmpy")
MARKER = "RESULT "


def recipe(master: str) -> str:
    """The code block of the master's section (### <master> ...) in docs/export.md."""
    text = DOCS.read_text(encoding="utf-8")
    section = re.search(rf"^### {master}\b.*?(?=^##)", text, flags=re.S | re.M)
    assert section, f"docs/export.md has no section for {master}"
    blocks = re.findall(r"^```python\n(.*?)^```", section.group(0), flags=re.S | re.M)
    assert len(blocks) == 1, f"the {master} section must hold one python block"
    return blocks[0]


HARNESS = textwrap.dedent("""
    import json, sys
    ssp, stop_time, step, signals = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), json.loads(sys.argv[4])
    result = run_{master}(ssp, stop_time, step, signals)
    print({marker!r} + json.dumps({{name: [v.item() if hasattr(v, "item") else v for v in values]
                                   for name, values in result.items()}}), flush=True)
""")


def run_master(master: str, ssp: Path, stop_time: float, step: float, signals: dict[str, str], cwd=None
               ) -> dict[str, np.ndarray]:
    """The recipe of `master` run on `ssp` (in the working folder `cwd`, default this process's): {"time": ...,
    "component.variable": ...} at every communication point."""
    code = recipe(master) + HARNESS.format(master=master, marker=MARKER)
    completed = subprocess.run([sys.executable, "-c", code, str(ssp), repr(stop_time), repr(step),
                                json.dumps(signals)], capture_output=True, text=True, timeout=900, cwd=cwd)
    assert completed.returncode == 0, completed.stderr[-3000:]
    line = next((line for line in completed.stdout.splitlines() if line.startswith(MARKER)), None)
    assert line is not None, completed.stdout[-3000:] + completed.stderr[-3000:]
    return {name: np.asarray(values) for name, values in json.loads(line[len(MARKER):]).items()}
