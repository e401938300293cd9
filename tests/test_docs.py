"""The documents: every relative link points to a file (and a heading) that exists, no text (the documents, and
every tracked code, test, data, tool and benchmark file) refers to documents outside the repository, and
BENCHMARKS.md is what benchmarks/report.py makes of the committed results."""

import importlib.util
import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCUMENTS = sorted({ROOT / "README.md", ROOT / "BENCHMARKS.md", *(ROOT / "docs").glob("*.md"),
                    *(ROOT / "sdl_fmu").rglob("*.md")})
LINK = re.compile(r"(?<!!)\[[^\]]*\]\(([^)\s]+)\)|!\[[^\]]*\]\(([^)\s]+)\)")


def prose(text: str) -> str:
    """The text outside fenced code blocks and inline code spans (links there are examples, not links)."""
    text = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)
    return re.sub(r"`[^`\n]*`", "", text)


def anchors(path: Path) -> set[str]:
    """GitHub's heading anchors: lower case, punctuation dropped, spaces to hyphens, repeats numbered -1, -2, ..."""
    seen: dict[str, int] = {}
    result = set()
    for line in re.sub(r"^```.*?^```", "", path.read_text(), flags=re.S | re.M).splitlines():
        heading = re.match(r"#{1,6} (.*)", line)
        if not heading:
            continue
        slug = re.sub(r"[^\w\- ]", "", heading[1].strip().lower()).replace(" ", "-")
        count = seen.get(slug, 0)
        seen[slug] = count + 1
        result.add(slug if count == 0 else f"{slug}-{count}")
    return result


def links(path: Path) -> list[str]:
    return [a or b for a, b in LINK.findall(prose(path.read_text()))]


def test_the_documents_exist():
    names = {str(p.relative_to(ROOT)) for p in DOCUMENTS}
    assert {"README.md", "BENCHMARKS.md", "docs/README.md", "sdl_fmu/dynamics/simple.md",
            "sdl_fmu/dynamics/advanced.md"} <= names


@pytest.mark.parametrize("document", DOCUMENTS, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_resolves(document):
    broken = []
    for target in links(document):
        if re.match(r"[a-z]+:", target):  # https:, mailto: ...
            continue
        file, _, anchor = target.partition("#")
        linked = (document.parent / file).resolve() if file else document
        if not linked.exists():
            broken.append(f"{target}: no file {linked}")
        elif anchor and linked.suffix == ".md" and anchor not in anchors(linked):
            broken.append(f"{target}: no heading #{anchor} in {linked.relative_to(ROOT)}")
    assert not broken, "\n".join(broken)


def test_the_link_checker_sees_a_broken_link(tmp_path):
    (tmp_path / "a.md").write_text("# Title A\n\n## Second `part` (x)\n")
    (tmp_path / "b.md").write_text("[ok](a.md#second-part-x) [gone](a.md#third) [missing](c.md) `[code](d.md)`\n")
    assert links(tmp_path / "b.md") == ["a.md#second-part-x", "a.md#third", "c.md"]
    assert anchors(tmp_path / "a.md") == {"title-a", "second-part-x"}


# Documents the repository does not hold: the project's contract and issue texts, the SDL seed texts.
FOREIGN_REFERENCE = re.compile(r"\bSPEC\b|§|\b[Ii]ssues? ?#?\d+|\b[Tt]he issue\b|\b[Ii]ssue asks\b|[Ss]eed texts?|"
                               r"\b[Tt]he seed(?:'s| examples?\b)|seed (?:A|BRK|RSA) example|\bCEO\b")


def tracked_files() -> list[Path]:
    """The files git tracks (a checkout without git: every file, caches left out)."""
    try:
        listing = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True).stdout
        return [ROOT / name for name in listing.decode().split("\0") if name]
    except (OSError, subprocess.CalledProcessError):
        return [p for p in ROOT.rglob("*") if p.is_file() and not
                {".git", ".venv", "__pycache__", ".pytest_cache", "dist", "runs"} & set(p.relative_to(ROOT).parts)]


def is_text(path: Path) -> bool:
    data = path.read_bytes()
    try:
        data.decode("utf-8")
    except UnicodeDecodeError:
        return False  # a PNG
    return b"\0" not in data


# Every other tracked text file: code, tests, shipped data (scenarios, tires, vehicle maps, interface JSON),
# tools, benchmarks and their results, CI. This file is left out: it must spell the pattern.
SOURCES = sorted(p for p in tracked_files()
                 if p not in DOCUMENTS and p != Path(__file__).resolve() and p.is_file() and is_text(p))


# A document a text names: a path with a folder (docs/results.md, sdl_fmu/dynamics/simple.md) or an upper-case name
# (README.md), read from the repository's top or from the naming file's folder
CITED = re.compile(r"(?<![\w/.-])((?:[\w.-]+/)+[\w.-]+\.md|[A-Z][A-Z0-9_]+\.md)\b")

def test_every_document_a_text_names_exists():
    missing = [f"{text.relative_to(ROOT)}:{number}: {name}" for text in SOURCES
               for number, line in enumerate(text.read_text(encoding="utf-8").splitlines(), 1)
               for name in CITED.findall(line)
               if not (ROOT / name).exists() and not (text.parent / name).exists()]
    assert not missing, "\n".join(missing)
    assert CITED.findall("see docs/results.md, README.md and EGO_MODEL_INTERFACE.md; not x.md or a/b.mdx") == [
        "docs/results.md", "README.md", "EGO_MODEL_INTERFACE.md"]


TEST_FILES = sorted((ROOT / "tests").rglob("test_*.py"))
# A test file a text names: by its path (tests/cosim/test_closing.py) or by its name alone (test_closing.py)
TEST_FILE = re.compile(r"(?<![\w/.-])((?:tests/(?:[\w-]+/)*)?test_\w+\.py)\b")


def test_every_test_file_a_text_names_exists():
    paths = {str(p.relative_to(ROOT)) for p in TEST_FILES}
    names = {p.name for p in TEST_FILES}
    missing = [f"{text.relative_to(ROOT)}:{number}: {name}" for text in DOCUMENTS + SOURCES
               for number, line in enumerate(text.read_text(encoding="utf-8").splitlines(), 1)
               for name in TEST_FILE.findall(line) if name not in (paths if "/" in name else names)]
    assert not missing, "\n".join(missing)
    assert TEST_FILE.findall("tests/cosim/test_closing.py, test_docs.py; not my_test_x.py or tests.py") == [
        "tests/cosim/test_closing.py", "test_docs.py"]


def test_the_test_folders_mirror_the_package():
    """Test files sit in tests/ (what crosses the stages) or in tests/<stage>/ for a stage of sdl_fmu/, or in
    tests/hostile/ (the hostile-input tests of every stage), one name once (the folders are not packages):
    tests/README.md."""
    stages = {p.parent.name for p in (ROOT / "sdl_fmu").glob("*/__init__.py")}
    folders = {p.parent.relative_to(ROOT / "tests") for p in TEST_FILES}
    assert {str(folder) for folder in folders} - {"."} <= stages | {"hostile"}
    assert len({p.name for p in TEST_FILES}) == len(TEST_FILES)


@pytest.mark.parametrize("text", DOCUMENTS + SOURCES, ids=lambda p: str(p.relative_to(ROOT)))
def test_no_text_refers_to_documents_outside_the_repository(text):
    found = [f"{text.relative_to(ROOT)}:{number}: {line.strip()}" for number, line in
             enumerate(text.read_text(encoding="utf-8").splitlines(), 1) if FOREIGN_REFERENCE.search(line)]
    assert not found, "\n".join(found)


def test_the_foreign_reference_check_sees_references_and_spares_names():
    assert SOURCES and {"sdl_fmu/api.py", "scenarios/demo.sdl", "scenarios/tires/ice.tir", "tests/conftest.py",
                        "modelDescription/EgoVehicleSimple.json", ".ci/run"} <= {
        str(p.relative_to(ROOT)) for p in SOURCES}
    for foreign in ["(SPEC §2)", "SPEC section 4", "the SPEC's keys", "§5", "issue 7, item 2", "Issue #16",
                    "the issue asks", "The issue's reproducer", "the\n    # issue asks", "(seed text)",
                    "The seed's BRK use case", "the seed examples", "the four seed BRK examples", "the CEO"]:
        assert any(FOREIGN_REFERENCE.search(line) for line in foreign.splitlines()), foreign
    for own in ["ASPECT_RATIO = 0.60", "SPEC_METRICS = {", "spec_closed_forms = true", "--seed 7", "seed=3",
                "reproducible from the seed: the same events", "issued handles", "inspect"]:
        assert not FOREIGN_REFERENCE.search(own), own


def test_benchmarks_md_is_generated_from_the_committed_results():
    spec = importlib.util.spec_from_file_location("benchmarks_report", ROOT / "benchmarks" / "report.py")
    report = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(report)
    assert (ROOT / "BENCHMARKS.md").read_text() == report.render(ROOT / "benchmarks" / "results"), \
        "BENCHMARKS.md differs from the results: run python benchmarks/report.py"


def test_ci_runs_the_readmes_test_command():
    """.ci/run ends in the Quick start's command that installs and runs every test (pip quiet in CI)."""
    command = next(line for line in (ROOT / "README.md").read_text().splitlines()
                   if line.startswith("python3 -m venv") and "pytest" in line)
    ci = (ROOT / ".ci" / "run").read_text().strip().splitlines()[-1]
    assert ci.replace("pip install -q ", "pip install ") == command
    assert "-n 2 --dist loadgroup" in command  # both cores, the wine tests on one worker (tests/conftest.py)
