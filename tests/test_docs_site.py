"""The docs site has a page and a picture for every registered env, generated from its spec.

The site itself is built by ``scripts/docs.sh`` (Sphinx with ``-W``, in CI); these tests check,
without Sphinx, what it is made of: the page generator of ``docs/_ext/sensorgym_docs.py``
writes one page per id with the spec's sections, the env's default rules, its row of the
committed results and its changelog section, and ``docs/make_pictures.py`` has committed one
picture and one animated GIF per id.
"""

from __future__ import annotations

import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import pytest
from PIL import Image

from sensorgym.envs import ENV_IDS
from tests.pending import having

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
SPEC_SECTIONS = ("Action Space", "Observation Space", "Rewards", "Episode End", "Arguments")


def _extension():
    path = DOCS / "_ext" / "sensorgym_docs.py"
    spec = importlib.util.spec_from_file_location("sensorgym_docs", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("sensorgym_docs", module)
    spec.loader.exec_module(module)
    return module


ext = _extension()


def test_the_envs_registered_are_the_seven_the_site_documents():
    # every env's page is generated; the pictures' rules cover all but the pending pictures
    assert set(having("picture", ENV_IDS)) == set(_pictures_script_rules())
    assert len(ENV_IDS) == 7


def _pictures_script_rules() -> dict[str, str]:
    path = DOCS / "make_pictures.py"
    spec = importlib.util.spec_from_file_location("make_pictures", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)  # defines RULES; renders only under __main__
    return module.RULES


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_every_env_page_has_the_spec_sections_of_its_docstring(env_id):
    page = ext.env_page(env_id)
    headings = re.findall(r"^## (.+?)\s*$", page, flags=re.M)
    for section in SPEC_SECTIONS:
        assert section in headings, f"{env_id}: no '## {section}' on its page"
    assert "## Registration" in page and "## PettingZoo" in page
    assert f"`max_episode_steps` | {_max_steps(env_id)} |" in page
    assert "import env, parallel_env" in page
    # the picture the page shows is the committed one
    assert f"](../assets/envs/{ext.env_name(env_id)}.png)" in page
    # reST roles became MyST roles with full names (Sphinx resolves them unambiguously)
    assert not re.search(r":(class|func|mod|meth|attr):`", page)
    for target in re.findall(r"\{py:\w+\}`~?(?:[^`<]+<)?([^`>]+)>?`", page):
        assert target.startswith("sensorgym."), f"{env_id}: unresolved target {target!r}"


def _max_steps(env_id: str) -> int:
    import gymnasium as gym

    return gym.spec(env_id).max_episode_steps


def test_a_page_section_is_the_docstring_text_not_a_copy():
    """The page's Rewards section is generated from the class docstring itself."""
    import inspect

    import gymnasium as gym

    env_id = "sensorgym/StereoPlacement-v0"
    cls = gym.envs.registration.load_env_creator(gym.spec(env_id).entry_point)
    _, sections = ext._split(inspect.getdoc(cls))
    page = ext.env_page(env_id)
    rewards = page.split("## Rewards\n", 1)[1].split("\n## ", 1)[0].strip()
    expected = ext._roles(sections["Rewards"], cls.__module__, cls.__name__, myst=True)
    assert rewards == expected.strip()


def test_a_section_left_to_the_base_env_comes_from_its_docstring():
    page = ext.env_page("sensorgym/BearingsManeuverBook-v0")
    action = page.split("## Action Space\n", 1)[1].split("\n## ", 1)[0]
    assert "From the docstring of" in action and "BearingsManeuverEnv" in action


@pytest.mark.parametrize("env_id", having("picture", ENV_IDS))
def test_every_env_has_a_committed_picture(env_id):
    path = ext.picture_path(env_id)
    assert path.is_file(), f"{path.relative_to(ROOT)}: run .venv/bin/python docs/make_pictures.py"
    tracked = subprocess.run(
        ["git", "ls-files", "--error-unmatch", str(path.relative_to(ROOT))],
        cwd=ROOT,
        capture_output=True,
    )
    # without git (an unpacked sdist) the file is all there is to check
    assert tracked.returncode != 1, f"{path.relative_to(ROOT)} is not committed"
    with Image.open(path) as im:
        assert im.format == "PNG" and min(im.size) >= 200


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_every_env_has_a_committed_animated_gif_under_1_mb(env_id):
    path = ext.animation_path(env_id)
    rel = path.relative_to(ROOT)
    assert path.is_file(), f"{rel}: run .venv/bin/python docs/make_pictures.py --only gif"
    assert path.stat().st_size < 1_000_000, f"{rel}: {path.stat().st_size} bytes"
    tracked = subprocess.run(
        ["git", "ls-files", "--error-unmatch", str(rel)], cwd=ROOT, capture_output=True
    )
    # without git (an unpacked sdist) the file is all there is to check
    assert tracked.returncode != 1, f"{rel} is not committed"
    with Image.open(path) as im:
        assert im.format == "GIF" and im.is_animated and im.n_frames > 1
        assert min(im.size) >= 150
    assert f"](../assets/envs/{ext.env_name(env_id)}.gif)" in ext.env_page(env_id)


def _section(page: str, title: str) -> str:
    assert f"\n## {title}\n" in page, f"no '## {title}' on the page"
    return page.split(f"\n## {title}\n", 1)[1].split("\n## ", 1)[0]


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_every_env_page_lists_its_default_rules_one_line_each(env_id):
    from sensorgym.agents.registry import ABLATIONS, default_rules

    rules = _section(ext.env_page(env_id), "Rules")
    lines = [line for line in rules.splitlines() if line.startswith("- `")]
    assert [line.split("`")[1] for line in lines] == default_rules(env_id)
    for line in lines:  # the rule's class and the first sentence of its docstring
        assert re.match(r"- `[^`]+` \(\{py:class\}`~sensorgym\.agents\.[\w.]+`\): \S", line)
    for name in ABLATIONS.get(env_id, ()):
        assert f"`{name}`" in rules.split("ablations", 1)[1]


def test_a_rule_line_is_the_first_sentence_of_its_class_docstring():
    from sensorgym.agents.stereo_placement import HoldPosition

    rules = _section(ext.env_page("sensorgym/StereoPlacement-v0"), "Rules")
    first = ext.first_sentence(HoldPosition.__doc__)
    assert first.endswith(".") and "\n" not in first
    assert (
        f"- `hold-position` ({{py:class}}`~{HoldPosition.__module__}.HoldPosition`): {first}"
        in (rules)
    )
    assert ext.first_sentence("A (b. c) ``d. e``. F.") == "A (b. c) ``d. e``."


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_every_env_page_has_its_row_of_the_results_or_no_scores_yet(env_id):
    import json

    results = _section(ext.env_page(env_id), "Results")
    path = ext.scores_path(env_id)
    if not path.is_file():
        assert "No scores yet" in results
        return
    doc = json.loads(path.read_text())
    best = ext._tables()._score_doc(ext.env_name(env_id))["best_rule"]
    assert f"| best rule `{best}` | {doc['results'][best]['mean']:.3f} |" in results
    for name in (n for n in doc["results"] if ":" in n):
        paired = doc["paired"][name]["mean"]
        assert f"| `{name}` | {doc['results'][name]['mean']:.3f} |" in results
        assert f"| {paired:+.3f} |" in results


def test_an_env_without_committed_scores_says_so(monkeypatch):
    pending = [e for e in ENV_IDS if e not in having("scores", ENV_IDS)]
    for env_id in pending:
        assert not ext.scores_path(env_id).exists()
        assert "No scores yet" in _section(ext.env_page(env_id), "Results")
    # every env may have its scores: the page of one whose file is missing still says so
    env_id = ENV_IDS[-1]
    monkeypatch.setattr(ext, "scores_path", lambda e: ROOT / "docs" / "scores" / "missing.json")
    assert "No scores yet" in _section(ext.env_page(env_id), "Results")


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_every_env_page_has_its_changelog_section(env_id):
    changelog = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
    environments = changelog.split("\n## Environments\n", 1)[1]
    own = environments.split(f"### `{env_id}`\n", 1)[1].split("\n### ", 1)[0].split("\n## ")[0]
    history = _section(ext.env_page(env_id), "Version History")
    assert "### In CHANGELOG.md" in history
    assert own.strip() in history


def test_contributing_and_the_public_api_are_pages_of_the_site():
    index = (DOCS / "index.md").read_text()
    for page in ("contributing", "public-api", "changelog"):
        assert f"\n{page}\n" in index, f"docs/{page}.md is not in the toctree"
    assert "```{include} ../CONTRIBUTING.md" in (DOCS / "contributing.md").read_text()
    assert "```{include} ../CHANGELOG.md" in (DOCS / "changelog.md").read_text()
    public = (DOCS / "public-api.md").read_text()
    start = re.search(r":start-after: (.+)", public).group(1).strip()
    end = re.search(r":end-before: (.+)", public).group(1).strip()
    readme = (ROOT / "README.md").read_text()
    section = readme.split("\n## Public API\n", 1)[1].split("\n## ", 1)[0]
    assert start in section and end in section
    assert "| import | what it gives |" in section.split(start, 1)[1].split(end, 1)[0]


def test_generated_pages_are_one_per_id_and_in_the_toctree(tmp_path, monkeypatch):
    monkeypatch.setattr(ext, "PAGES", tmp_path)
    (tmp_path / "Retired-v0.md").write_text("# an id no longer registered\n")
    written = ext.write_env_pages()
    names = sorted(p.name for p in tmp_path.glob("*.md"))
    assert names == sorted(["index.md", *(f"{ext.env_name(i)}.md" for i in ENV_IDS)])
    assert len(written) == len(ENV_IDS) + 1
    index = (tmp_path / "index.md").read_text()
    for env_id in ENV_IDS:
        assert f"\n{ext.env_name(env_id)}\n" in index


def test_markdown_tables_and_sections_become_rest_for_autodoc():
    lines = [
        "Summary.",
        "",
        "## Action Space",
        "",
        "| index | action | unit |",
        "|-------|--------|------|",
        "| 0     | ``a | b`` turn | rad/s |",
        "",
        "A :class:`.simulation` reference stays text.",
    ]
    rst = ext.markdown_to_rst(lines)
    assert ".. rubric:: Action Space" in rst
    assert ".. list-table::" in rst
    assert "   * - 0" in rst and "     - ``a | b`` turn" in rst
    assert not any(line.startswith("|") for line in rst)


def test_rest_literal_blocks_become_markdown_code_on_the_env_pages():
    text = "The prediction::\n\n    x = F x\n\n::\n\n    P = F P Fᵀ + Q\n"
    assert ext._roles(text, "sensorgym.envs", None, myst=True) == (
        "The prediction:\n\n    x = F x\n\n\n\n    P = F P Fᵀ + Q\n"
    )


def test_relative_targets_resolve_to_where_the_object_is_defined():
    module = "sensorgym.envs.stereo_pointing.crowded"
    assert ext.resolve_target(".simulation", module) == "sensorgym.envs.stereo_pointing.simulation"
    assert (
        ext.resolve_target("~.simulation.PointingParams".lstrip("~"), module)
        == "sensorgym.envs.stereo_pointing.simulation.PointingParams"
    )
    # a name re-exported by a package is documented where it is defined
    assert ext.resolve_target("StraightCourse", "sensorgym.agents") == (
        "sensorgym.agents.bearings_maneuver.StraightCourse"
    )
    assert ext.resolve_target("no_such_thing", module) == "no_such_thing"


def test_the_site_build_is_wired_into_ci_and_the_docs_extra():
    import tomllib

    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"][
        "optional-dependencies"
    ]
    assert {re.split(r"[<>=]", d)[0] for d in extras["docs"]} >= {"sphinx", "furo", "myst-parser"}
    script = (ROOT / "scripts" / "docs.sh").read_text()
    assert re.search(r'sphinx-build"? -W --keep-going -b html docs docs/_build/html', script)
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    assert "bash scripts/test.sh" in ci and "bash scripts/docs.sh" in ci
    assert ci.index("bash scripts/docs.sh") > ci.index("bash scripts/test.sh")
    assert "docs/_build/" in (ROOT / ".gitignore").read_text().splitlines()


def test_every_rule_module_has_a_rule_family_page():
    rules = DOCS / "api" / "rules"
    pages = "\n".join(p.read_text() for p in sorted(rules.glob("*.md")))
    agents = ROOT / "agents"
    modules = sorted(
        p.stem for p in agents.glob("*.py") if p.stem not in ("__init__", "registry", "protocol")
    )
    assert modules
    for module in modules:
        assert f".. automodule:: sensorgym.agents.{module}\n" in pages, module
    toctree = (rules.parent / "agents.md").read_text()
    for page in rules.glob("*.md"):
        assert f"rules/{page.stem}\n" in toctree, page.name
