"""The documentation site (mkdocs.yml) builds with ``mkdocs build --strict``: every public name has
a section in the API reference, the equations render, the figures appear, and a broken link or a
reference to an undocumented name fails the build. The tutorials are rendered as committed (their
execution is tests/test_tutorials.py's)."""

from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / "fatigue_pin"


def _mkdocs(config: Path, site: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "FATIGUE_PIN_DOCS_EXECUTE": "false", "NO_MKDOCS_2_WARNING": "1"}
    return subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-f", str(config), "-d", str(site)],
                          capture_output=True, text=True, env=env, cwd=site.parent, timeout=600)


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("site") / "site"
    done = _mkdocs(REPO / "mkdocs.yml", out)
    assert done.returncode == 0, f"mkdocs build --strict failed:\n{done.stdout[-4000:]}\n{done.stderr[-6000:]}"
    return out


def _public_names(path: Path) -> list[str]:
    """``__all__`` of a module, or else the names it defines at top level without a leading underscore."""
    tree = ast.parse(path.read_text())
    names: list[str] = []
    for node in tree.body:
        if isinstance(node, (ast.Assign, ast.AugAssign, ast.AnnAssign)):
            target = node.targets[0] if isinstance(node, ast.Assign) else node.target
            if isinstance(target, ast.Name) and target.id == "__all__":
                names += list(ast.literal_eval(node.value))
    if names:
        return names
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.append(node.name)
        elif isinstance(node, ast.Assign):
            names += [t.id for t in node.targets if isinstance(t, ast.Name)]
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            names.append(node.target.id)
    return [n for n in names if not n.startswith("_")]


def _modules() -> list[tuple[str, Path]]:
    out = []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE)
        if len(rel.parts) == 2 and rel.name != "__init__.py":
            out.append((rel.parts[0], path))
    return out


def every_public_name_of_every_module_has_a_section(site: Path) -> None:
    missing = []
    for package, path in _modules():
        html = (site / "reference" / package / "index.html").read_text()
        module = f"fatigue_pin.{package}.{path.stem}"
        for name in [None, *_public_names(path)]:
            anchor = module if name is None else f"{module}.{name}"
            if f'id="{anchor}"' not in html:
                missing.append(anchor)
    assert missing == [], f"no section in the API reference for: {missing}"


def every_name_of_the_public_api_has_a_section_and_a_line_in_api_md(site: Path) -> None:
    from fatigue_pin import _API

    api = (REPO / "docs" / "api.md").read_text()
    for name, module in _API.items():
        html = (site / "reference" / module.split(".")[1] / "index.html").read_text()
        assert f'id="{module}.{name}"' in html, f"{name} ({module}) has no section"
        assert f"][{module}.{name}]" in api, f"docs/api.md does not link {name} to its section"


def equations_render_and_figures_appear(site: Path) -> None:
    for page in ("fatigue", "ocp"):
        html = (site / page / "index.html").read_text()
        assert html.count('class="arithmatex"') >= 3, f"{page}.md: no rendered equations"
    assert "tex-mml-chtml.js" in (site / "fatigue" / "index.html").read_text()
    shown = 0
    for md in sorted((REPO / "docs").glob("*.md")):
        for target in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", md.read_text()):
            assert (site / target).is_file(), f"{md.name}: figure {target} is not in the site"
            page = site / md.stem / "index.html" if md.stem != "index" else site / "index.html"
            assert f'src="../{target}"' in page.read_text(), f"{md.name}: figure {target} is not on the page"
            shown += 1
    assert shown >= 10
    for nb in sorted((REPO / "docs" / "tutorials").glob("*.ipynb")):
        assert (site / "tutorials" / nb.stem / "index.html").is_file()


def test_the_built_site_has_every_name_the_equations_and_the_figures(site):
    """The three checks of the built site in one test, so that one worker builds it (25-40 s)."""
    every_public_name_of_every_module_has_a_section(site)
    every_name_of_the_public_api_has_a_section_and_a_line_in_api_md(site)
    equations_render_and_figures_appear(site)


def _mini_site(tmp_path: Path, page: str) -> subprocess.CompletedProcess:
    """A one-page site with the project's strict settings and API handler."""
    docs = tmp_path / "docs"
    docs.mkdir(parents=True)
    (docs / "index.md").write_text(page)
    config = tmp_path / "mkdocs.yml"
    config.write_text(textwrap.dedent(f"""\
        site_name: check
        strict: true
        validation: {{links: {{not_found: warn, anchors: warn}}}}
        plugins:
          - mkdocstrings: {{handlers: {{python: {{paths: ["{REPO}"]}}}}}}
        """))
    return _mkdocs(config, tmp_path / "site")


def test_the_strict_build_fails_on_a_broken_link_or_an_undocumented_reference(tmp_path):
    assert _mini_site(tmp_path / "ok", "# ok\n\n[`preset`][fatigue_pin.fatigue.presets.preset]\n\n"
                      "::: fatigue_pin.fatigue.presets.preset\n").returncode == 0
    broken_link = _mini_site(tmp_path / "link", "# x\n\nSee [the page](nowhere.md).\n")
    assert broken_link.returncode != 0 and "nowhere.md" in broken_link.stderr
    undocumented = _mini_site(tmp_path / "ref", "# x\n\n[`nothing`][fatigue_pin.fatigue.presets.no_such_name]\n")
    assert undocumented.returncode != 0 and "no_such_name" in undocumented.stderr
