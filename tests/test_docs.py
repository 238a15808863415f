"""The front door stays small and its links resolve (the site itself is checked by `make docs`, mkdocs --strict);
the command-line reference lists every option; every number a page takes from a result file is the file's."""
import argparse
import importlib.util
import json
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LINK = re.compile(r"\]\(([^)\s]+)\)")


def _hooks():
    spec = importlib.util.spec_from_file_location("docs_hooks", ROOT / "docs" / "hooks.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


hooks = _hooks()


def _relative_links(path: Path):
    for target in LINK.findall(path.read_text()):
        if re.match(r"[a-z]+:", target) or target.startswith("#"):
            continue
        yield target.split("#")[0]


def test_readme_is_at_most_15_kb():
    assert len((ROOT / "README.md").read_bytes()) <= 15 * 1024


def test_readme_and_docs_relative_links_resolve():
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    generated = {ROOT / "docs" / path for path in hooks.GENERATED}   # made by the build (docs/hooks.py)
    broken = [f"{page.relative_to(ROOT)} -> {target}" for page in pages for target in _relative_links(page)
              if not (page.parent / target).exists() and (page.parent / target).resolve() not in generated]
    assert not broken, broken


def test_every_api_module_page_names_an_existing_module():
    for page in sorted((ROOT / "docs" / "api").glob("jaxarm*.md")):
        for module in re.findall(r"^::: ([\w.]+)", page.read_text(), flags=re.M):
            parts = module.split(".")
            assert (ROOT.joinpath(*parts).with_suffix(".py").exists() or ROOT.joinpath(*parts, "__init__.py").exists()), \
                f"{page.name}: {module}"


def test_cli_reference_lists_every_command_and_option():
    from jaxarm import cli

    page = hooks.cli_reference()
    for name in cli.COMMANDS:
        section = page.split(f"\n## jaxarm {name}\n")[1].split("\n## jaxarm ")[0]
        for action in cli.parser(name)._actions:
            if isinstance(action, argparse._HelpAction):
                continue
            shown = action.option_strings[0] if action.option_strings else action.metavar or action.dest
            assert f"<code>{shown}" in section, f"jaxarm {name}: {shown} missing from the command-line reference"
    train = page.split("\n## jaxarm train\n")[1].split("\n## jaxarm ")[0]
    assert re.search(r"<code>--preset NAME</code> \| – \| train with a stored preset", train)
    assert re.search(r"<code>--networks NETWORKS</code> \| <code>4</code> \|", train)


#: The headline numbers each page must take from its result file (a placeholder, or on README.md a marker after the
#: written-out number): the reproduction counts of both arms, and on the site the distances after entry.
COUNTS = [(f"reproduce_{arm}.json", f"targets.{target}.{mode}") for arm in ("musculoskeletal", "simple")
          for target in ("left", "bottom") for mode in ("seeds", "top30", "paper")]
DISTANCES = [("reproduce_musculoskeletal.json", f"targets.{target}.measures.{mode}.distance_after_m.mean")
             for target in ("left", "bottom") for mode in ("seeds", "top30")]
HEADLINES = {"README.md": COUNTS, "docs/index.md": COUNTS + DISTANCES, "docs/reproducing.md": COUNTS + DISTANCES}


def _references(text: str) -> set[tuple[str, str]]:
    specs = [m.group(1) for pattern in (hooks.PLACEHOLDER, hooks.MARKER) for m in pattern.finditer(text)]
    return {tuple(p.strip() for p in spec.split(":")[:2]) for spec in specs}


@pytest.mark.parametrize("page", sorted(HEADLINES))
def test_headline_numbers_come_from_their_result_files(page):
    text = (ROOT / page).read_text()
    missing = [f"{f} : {p}" for f, p in HEADLINES[page] if (f, p) not in _references(text)]
    assert not missing, f"{page} states these headline numbers without their result file: {missing}"


def test_every_number_taken_from_a_result_file_is_the_files():
    """A written-out number followed by <!-- result: FILE : PATH --> (README.md, read unrendered on GitHub) must be
    the file's; every placeholder must resolve (the site's build renders them, docs/hooks.py)."""
    for page in [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]:
        text = page.read_text()
        assert not hooks.marker_mismatches(text), f"{page.relative_to(ROOT)}: {hooks.marker_mismatches(text)}"
        hooks.render(text)


def test_user_pages_cite_nothing_outside_the_repository():
    """A newcomer's pages state the facts they rely on, cited to the paper or the authors' code, not to the project's
    extracted specification (outside the repository) or to issue numbers."""
    outside = re.compile(r"spec §|reference_values\.md|\bissue('s| \d+)", re.I)
    for page in USER_PAGES:
        hits = [m.group(0) for m in outside.finditer((ROOT / page).read_text())]
        assert not hits, f"{page}: {hits}"


#: Pages that say what to run, what it prints, how long it takes and what it means; their history (what changed
#: when, superseded numbers, search logs) is in the record: docs/changelog.md, docs/results.md, docs/searches.md.
USER_PAGES = ("README.md", "docs/index.md", "docs/getting-started.md", "docs/reproducing.md", "docs/model.md",
              "docs/robot.md", "docs/evolution.md")
HASH = re.compile(r"(?<![\w/.-])(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}(?![\w-])")
DATE = re.compile(r"\b20\d\d-\d\d-\d\d\b")


def _prose(text: str) -> str:
    """A page's text less link targets, result placeholders and the numbers written out before result markers (a
    result file's date is provenance, not narrative), and the authors' ModelDB snapshot (their code, not ours)."""
    text = re.sub(r"\]\([^)]*\)", "]()", text)
    text = re.sub(r"\S*<!--\s*result:.*?-->", "", text)
    text = re.sub(r"\{\{[^{}]*\}\}", "", text)
    return re.sub(r"snapshot [0-9a-f]{7}", "", text)


@pytest.mark.parametrize("page", USER_PAGES)
def test_user_pages_carry_no_commit_hashes_and_no_dates(page):
    text = _prose((ROOT / page).read_text())
    hits = [m.group(0) for pattern in (HASH, DATE) for m in pattern.finditer(text)]
    assert not hits, f"{page}: {hits} (history goes to docs/changelog.md, docs/results.md or docs/searches.md)"


def test_the_prose_filter_sees_a_hash_and_a_date():
    assert HASH.search(_prose("fixed in 9ed3104 (every P cell)")) and DATE.search(_prose("rerun on 2026-12-03"))
    assert not HASH.search(_prose("[x](searches.md#18-x-2026-12-04) ModelDB 183014, snapshot 1dd5002, 1e-3"))
    assert not DATE.search(_prose("run on 2026-12-05<!-- result: reproduce_simple.json : date --> on"))


def test_a_tutorials_links_to_the_docs_resolve_on_the_site():
    html = '<a href="../docs/reproducing.md#success-counts">x</a> <a href="../docs/cli.md">y</a> <a href="#z">z</a>'
    assert hooks.notebook_links(html) == ('<a href="../../reproducing/#success-counts">x</a> '
                                          '<a href="../../cli/">y</a> <a href="#z">z</a>')
    for path in sorted((ROOT / "notebooks").glob("*.ipynb")):
        for target in re.findall(r"\]\(([^)\s]+)\)", path.read_text()):
            if re.match(r"[a-z]+:", target) or target.startswith("#"):
                continue
            assert target.startswith("../docs/"), f"{path.name}: {target} (link the docs as ../docs/PAGE.md)"
            assert (ROOT / "notebooks" / target.split("#")[0]).exists(), f"{path.name}: {target}"


def test_a_result_path_indexes_a_list_by_its_position():
    data = json.loads((ROOT / "docs/results/wam_tracking_original.json").read_text())
    per_seed = data["summary"]["packets_per_seed"]
    received = hooks.result("wam_tracking_original.json : summary.packets_per_seed.2.received")
    assert received == str(per_seed[2]["received"])
    with pytest.raises(hooks.ResultError, match=f"at '{len(per_seed)}'"):
        hooks.result(f"wam_tracking_original.json : summary.packets_per_seed.{len(per_seed)}.received")
