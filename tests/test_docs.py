"""The front door stays small and its links resolve (the site itself is checked by `make docs`, mkdocs --strict)."""
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LINK = re.compile(r"\]\(([^)\s]+)\)")


def _relative_links(path: Path):
    for target in LINK.findall(path.read_text()):
        if re.match(r"[a-z]+:", target) or target.startswith("#"):
            continue
        yield target.split("#")[0]


def test_readme_is_at_most_15_kb():
    assert len((ROOT / "README.md").read_bytes()) <= 15 * 1024


def test_readme_and_docs_relative_links_resolve():
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    broken = [f"{page.relative_to(ROOT)} -> {target}" for page in pages for target in _relative_links(page)
              if not (page.parent / target).exists()]
    assert not broken, broken


def test_every_api_module_page_names_an_existing_module():
    for page in sorted((ROOT / "docs" / "api").glob("jaxarm*.md")):
        for module in re.findall(r"^::: ([\w.]+)", page.read_text(), flags=re.M):
            parts = module.split(".")
            assert (ROOT.joinpath(*parts).with_suffix(".py").exists() or ROOT.joinpath(*parts, "__init__.py").exists()), \
                f"{page.name}: {module}"
