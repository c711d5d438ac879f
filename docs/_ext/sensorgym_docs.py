"""The docs site's own Sphinx extension: one page per registered env, and docstrings that render.

Each registered env id gets a page generated at build time (``builder-inited``) into
``docs/envs/`` from what the package already says, so that no spec text is copied by hand:

* the Gymnasium class's docstring (the spec: Description, Action Space, Observation Space,
  Rewards, Starting State, Episode End, Arguments, Version History). A section the class leaves
  to the env it derives from (``BearingsManeuverBookEnv`` keeps ``BearingsManeuverEnv``'s spaces)
  is taken from that base class's docstring, and the page says so;
* the registration in :mod:`sensorgym.envs` (entry points, ``max_episode_steps``);
* the PettingZoo door: the module's ``parallel_env`` / ``env`` and its ParallelEnv class's
  docstring;
* the animation ``docs/assets/envs/<name>.gif`` and picture ``<name>.png`` that
  ``docs/make_pictures.py`` rendered (the build never renders);
* the rules of the env's default set, one line each from the rule class's docstring, and its
  ablations by name (:mod:`sensorgym.agents.registry`);
* its row of the results from the committed ``docs/scores/<id>.json`` (read through
  ``benchmarks/tables.py``), or "no scores yet";
* its version history: the env's section of ``CHANGELOG.md`` (under ``## Environments``).

The docstrings are Markdown sections with reST roles (``:class:`~x```). The env pages are MyST:
the roles become MyST roles. For autodoc (reST), :func:`markdown_to_rst` turns the ``## Section``
headings into rubrics and the pipe tables into list-tables. In both, a relative target
(``:mod:`.simulation```, ``:class:`StraightCourse```) is rewritten to the full name of the
object it names (:func:`resolve_target`), so that Sphinx links it instead of finding several
candidates.

Importing this module needs no Sphinx: ``tests/test_docs_site.py`` calls :func:`env_page`.
"""

from __future__ import annotations

import functools
import importlib
import importlib.util
import inspect
import itertools
import re
from pathlib import Path
from typing import Any

DOCS = Path(__file__).resolve().parents[1]
ROOT = DOCS.parent
#: the committed benchmark scores, one file per env id (``/`` written ``__``)
SCORES = DOCS / "scores"
CHANGELOG = ROOT / "CHANGELOG.md"
#: the generated pages (git-ignored, rewritten by every build)
PAGES = DOCS / "envs"
#: the committed pictures, one per env id (``docs/make_pictures.py``)
PICTURES = DOCS / "assets" / "envs"
#: the spec's sections, in the order of Gymnasium's ``cartpole.py``
SECTIONS = (
    "Description",
    "Action Space",
    "Observation Space",
    "Rewards",
    "Starting State",
    "Episode End",
    "Arguments",
    "Version History",
)
ROLE = re.compile(r":(?:py:)?(class|func|mod|meth|attr|data|obj|exc|const):`(~?)([^`]+)`")
HEADING = re.compile(r"^(#{2,4}) (.+?)\s*$")


def env_name(env_id: str) -> str:
    """``"sensorgym/StereoPointing-v0"`` → ``"StereoPointing-v0"``: the page's and picture's name."""
    return env_id.split("/", 1)[-1]


def picture_path(env_id: str) -> Path:
    """The committed picture of ``env_id``."""
    return PICTURES / f"{env_name(env_id)}.png"


def animation_path(env_id: str) -> Path:
    """The committed animated GIF of ``env_id``."""
    return PICTURES / f"{env_name(env_id)}.gif"


def scores_path(env_id: str) -> Path:
    """The committed benchmark scores of ``env_id`` (``sensorgym benchmark --out docs/scores``)."""
    return SCORES / f"{env_id.replace('/', '__')}.json"


# --- names ------------------------------------------------------------------------------------


@functools.cache
def _lookup(path: str) -> Any:
    """The object a dotted path names (a module, or an attribute chain inside one), or None."""
    parts = path.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        except Exception:  # a module that fails to import is not a target
            return None
        for attr in parts[i:]:
            if not hasattr(obj, attr):
                return None
            obj = getattr(obj, attr)
        return obj
    return None


def _canonical(path: str, obj: Any) -> str:
    """Where the object is defined (a class re-exported by a package is documented there)."""
    if inspect.ismodule(obj):
        return obj.__name__
    if inspect.isclass(obj) or inspect.isfunction(obj):
        module, qualname = getattr(obj, "__module__", None), getattr(obj, "__qualname__", "")
        if module and qualname and "<" not in qualname and _lookup(f"{module}.{qualname}") is obj:
            return f"{module}.{qualname}"
    return path


@functools.cache
def resolve_target(target: str, module: str, cls: str | None = None) -> str:
    """The full dotted name of a role's target written in ``module`` (and class ``cls``).

    ``.simulation`` is looked up the way a reader reads it: beside the module, then in the
    enclosing packages; a bare name in the class, the module, then the enclosing packages. A
    target found nowhere is returned unchanged (Sphinx shows it as code, unlinked).
    """
    if target.startswith("sensorgym."):
        obj = _lookup(target)
        return target if obj is None else _canonical(target, obj)
    rel = target.lstrip(".")
    prefixes = [f"{module}.{cls}"] if cls else []
    parts = module.split(".")
    prefixes += [".".join(parts[:i]) for i in range(len(parts), 0, -1)]
    for prefix in prefixes:
        path = f"{prefix}.{rel}"
        obj = _lookup(path)
        if obj is not None:
            return _canonical(path, obj)
    return target


def _roles(text: str, module: str, cls: str | None, myst: bool) -> str:
    """Every reST role's target resolved; as a MyST role when ``myst``."""

    def one(m: re.Match[str]) -> str:
        kind, tilde, target = m.groups()
        full = resolve_target(target, module, cls)
        # ~ shows the last component only; a resolved relative name shows what its author wrote
        text = f"{tilde}{full}"
        if not tilde and full != target and not target.startswith("sensorgym."):
            text = f"{target.lstrip('.')} <{full}>"
        return f"{{py:{kind}}}`{text}`" if myst else f":py:{kind}:`{text}`"

    text = ROLE.sub(one, text)
    if myst:
        # reST's "text::" before an indented literal block: Markdown shows the indented block
        # as code by itself, and the paragraph ends in one colon (or none when "::" stands alone)
        text = re.sub(r"^(\s*)::$", r"\1", text, flags=re.M)
        text = re.sub(r"(\S)::$", r"\1:", text, flags=re.M)
    return text


# --- Markdown in reST docstrings (autodoc) ----------------------------------------------------


def _cells(row: str) -> list[str]:
    """The cells of a pipe-table row; a ``|`` inside a code span is text."""
    cells, cell, fence = [], "", ""
    for token in re.split(r"(`+)", row.strip().strip("|")):
        if token.startswith("`"):
            # a code span opens and closes with the same run of backticks
            fence = "" if token == fence else (fence or token)
            cell += token
            continue
        if fence:
            cell += token
            continue
        first, *rest = token.split("|")
        cell += first
        for part in rest:
            cells.append(cell.strip())
            cell = part
    cells.append(cell.strip())
    return cells


def _is_table_row(line: str) -> bool:
    s = line.strip()
    return s.startswith("|") and s.endswith("|") and s.count("|") >= 2


def _is_rule(line: str) -> bool:
    return bool(re.fullmatch(r"\s*\|(\s*:?-{2,}:?\s*\|)+\s*", line))


def markdown_to_rst(lines: list[str]) -> list[str]:
    """A docstring's Markdown parts as reST: ``## Section`` → a rubric, a pipe table → a
    list-table (header row, then the body). Everything else is left as it is."""
    out: list[str] = []
    i = 0
    while i < len(lines):
        line = lines[i]
        heading = HEADING.match(line)
        if heading:
            out += [f".. rubric:: {heading.group(2)}", ""]
            i += 1
            continue
        if _is_table_row(line) and i + 1 < len(lines) and _is_rule(lines[i + 1]):
            indent = line[: len(line) - len(line.lstrip())]
            rows = [_cells(line)]
            i += 2
            while i < len(lines) and _is_table_row(lines[i]):
                rows.append(_cells(lines[i]))
                i += 1
            width = len(rows[0])
            if out and out[-1].strip():
                out.append("")
            out += [f"{indent}.. list-table::", f"{indent}   :header-rows: 1", ""]
            for row in rows:
                row = (row + [""] * width)[:width]
                for j, cell in enumerate(row):
                    lead = "* - " if j == 0 else "  - "
                    out.append(f"{indent}   {lead}{cell}".rstrip())
            out.append("")
            continue
        out.append(line)
        i += 1
    return out


def process_docstring(
    app: Any, what: str, name: str, obj: Any, options: Any, lines: list[str]
) -> None:
    """``autodoc-process-docstring``: Markdown sections and tables as reST, targets resolved.

    A method that inherits its docstring from a library class (``CoreEnv.step`` from
    ``gymnasium.Env``, Google style) points to it instead of showing it."""
    source = _inherited_from(obj, name) if what == "method" else None
    if source is not None and not source.startswith("sensorgym."):
        lines[:] = [f"As :py:meth:`{source}` (its docstring there)."]
        return
    if inspect.ismodule(obj):
        module, cls = obj.__name__, None
    else:
        module = getattr(obj, "__module__", None) or name.rsplit(".", 1)[0]
        owner = name[len(module) + 1 :].split(".") if name.startswith(module + ".") else []
        cls = owner[0] if what != "class" and len(owner) > 1 else None
        if what == "class":
            cls = owner[0] if owner else None
    converted = markdown_to_rst([_roles(line, module, cls, myst=False) for line in lines])
    if what in ("function", "method", "class") and _numpy_sections(converted):
        # napoleon only here: as an extension it would also read an attribute docstring whose
        # first line has a colon ("Steps of margin: …") as "type: description"
        from sphinx.ext.napoleon import Config
        from sphinx.ext.napoleon.docstring import NumpyDocstring

        config = Config(napoleon_google_docstring=False)
        converted = NumpyDocstring(converted, config, None, what, name, obj).lines()
    lines[:] = converted


def process_signature(
    app: Any, what: str, name: str, obj: Any, options: Any, signature: str | None, ret: str | None
) -> tuple[str | None, str | None]:
    """``autodoc-process-signature``: an alias in a union is shown by its name (Sphinx 9 writes
    ``TypeAliasForwardRef('ArrayLike') | None``)."""

    def clean(text: str | None) -> str | None:
        return None if text is None else re.sub(r"TypeAliasForwardRef\('([^']+)'\)", r"\1", text)

    return clean(signature), clean(ret)


def _inherited_from(obj: Any, name: str) -> str | None:
    """Where a method without a docstring of its own inherits it from (``module.Class.name``)."""
    if getattr(obj, "__doc__", None) or "." not in name:
        return None
    owner_path, attr = name.rsplit(".", 1)
    owner = _lookup(owner_path)
    if not inspect.isclass(owner):
        return None
    for base in owner.__mro__[1:]:
        if getattr(vars(base).get(attr), "__doc__", None):
            return f"{base.__module__}.{base.__qualname__}.{attr}"
    return None


def _numpy_sections(lines: list[str]) -> bool:
    """Whether a docstring has a numpy-style section (``Parameters`` over a ``---`` rule)."""
    return any(
        a.strip() in ("Parameters", "Returns", "Raises") and re.fullmatch(r"\s*-{3,}\s*", b)
        for a, b in itertools.pairwise(lines)
    )


# --- the env pages ----------------------------------------------------------------------------


def _split(doc: str) -> tuple[str, dict[str, str]]:
    """A Markdown docstring's text before its first ``## `` section, and its sections."""
    parts = re.split(r"^## (.+?)\s*$", doc, flags=re.M)
    return parts[0].strip(), {
        t.strip(): b.strip() for t, b in zip(parts[1::2], parts[2::2], strict=True)
    }


def _demote(text: str, levels: int) -> str:
    return re.sub(r"^(#{2,5}) ", lambda m: "#" * (len(m.group(1)) + levels) + " ", text, flags=re.M)


def _registration(env_id: str) -> Any:
    import gymnasium as gym

    import sensorgym.envs  # noqa: F401  (registers the ids)

    return gym.spec(env_id)


def _load(entry_point: str) -> Any:
    module, attr = entry_point.split(":")
    return getattr(importlib.import_module(module), attr)


def _parallel_class(module: Any, env_id: str) -> Any:
    from sensorgym.envs.shells import CoreParallelEnv

    found = [
        obj
        for obj in vars(module).values()
        if inspect.isclass(obj)
        and issubclass(obj, CoreParallelEnv)
        and obj.__module__ == module.__name__
        and getattr(obj, "env_id", None) == env_id
    ]
    (cls,) = found
    return cls


def first_sentence(doc: str) -> str:
    """The first sentence of a docstring's first paragraph (a full stop outside brackets and
    code spans, followed by a space), on one line."""
    text = " ".join(doc.strip().split("\n\n", 1)[0].split())
    depth, fence, i = 0, "", 0
    while i < len(text):
        ch = text[i]
        if ch == "`":
            run = re.match(r"`+", text[i:]).group()  # a code span opens and closes with one run
            fence = "" if run == fence else (fence or run)
            i += len(run)
            continue
        if not fence:
            if ch in "([":
                depth += 1
            elif ch in ")]":
                depth = max(0, depth - 1)
            elif depth == 0 and ch in ".!?" and text[i + 1 : i + 2] in (" ", ""):
                return text[: i + 1]
        i += 1
    return text


def rules_section(env_id: str) -> list[str]:
    """The ``## Rules`` section: every rule of :func:`~sensorgym.agents.registry.default_rules`
    with its class and the first sentence of the class's docstring, then the ablations by
    name. Each rule is built for the registered default params (the registry maps names to
    factories, not classes)."""
    from sensorgym.agents.registry import ABLATIONS, RULES, default_rules

    spec = _registration(env_id)
    # what gym.make(env_id) plays: the params type's defaults with the registration's fields
    params = _load(spec.entry_point).params_type(**spec.kwargs)
    names = default_rules(env_id)
    out = ["## Rules", ""]
    if not names:
        return [*out, "No rules are registered for this env.", ""]
    out += [
        "The rules `sensorgym benchmark` scores on this env by default "
        "({py:func}`~sensorgym.agents.registry.default_rules`), in registration order; "
        f"`sensorgym render --env {env_id} --rule NAME` plays one, `--rule NAME` of "
        "`sensorgym benchmark` scores one. A rule named `truth-…` reads the simulator's true "
        "state: it shows what knowing the truth buys, it is not fieldable.",
        "",
    ]
    for name in names:
        rule = type(RULES[env_id][name](params, lambda: None))
        line = _roles(
            first_sentence(inspect.getdoc(rule) or ""), rule.__module__, rule.__name__, True
        )
        out.append(f"- `{name}` ({{py:class}}`~{rule.__module__}.{rule.__qualname__}`): {line}")
    ablations = [name for name in RULES[env_id] if name in ABLATIONS.get(env_id, frozenset())]
    out.append("")
    if ablations:
        listed = ", ".join(f"`{name}`" for name in ablations)
        out += [
            "Also registered, left out of the default set as ablations of a default rule "
            f"({{py:data}}`~sensorgym.agents.registry.ABLATIONS`): {listed}. "
            "`sensorgym benchmark --rule NAME` (or `--all-rules`) scores them.",
            "",
        ]
    else:
        out += ["No ablations are registered for this env.", ""]
    return out


@functools.cache
def _tables() -> Any:
    """``benchmarks/tables.py``, which generates the docs' score tables from the same files."""
    import sys

    path = ROOT / "benchmarks" / "tables.py"
    spec = importlib.util.spec_from_file_location("sensorgym_benchmark_tables", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def results_section(env_id: str) -> list[str]:
    """The ``## Results`` section: the env's row of the committed benchmark — its best rule and
    that rule's mean, each shipped policy's mean and paired difference to it — or "no scores
    yet" when ``docs/scores/`` has no file for the env."""
    path = scores_path(env_id)
    rel = path.relative_to(ROOT).as_posix()
    out = ["## Results", ""]
    if not path.is_file():
        return [*out, f"No scores yet: `{rel}` is not committed.", ""]
    doc = _tables()._score_doc(env_name(env_id))
    settings, results = doc["settings"], doc["results"]
    best, paired = doc.get("best_rule"), doc.get("paired", {})
    out += [
        f"From `{rel}` (`sensorgym benchmark`, seed {settings['seed']}, "
        f"{settings['episodes']} episodes): mean episode return with its 95 % interval; the "
        f"paired difference is per episode, on the same scenarios, to the best rule `{best}`. "
        "Every rule's score, the headroom and the tail are in [Results](../results.md).",
        "",
        "| policy | mean return | ± 95 % | paired − best rule | paired 95 % interval |",
        "| --- | ---: | ---: | ---: | ---: |",
    ]
    if best in results:
        r = results[best]
        out.append(f"| best rule `{best}` | {r['mean']:.3f} | {r['ci95']:.3f} | | |")
    shipped = sorted(name for name in results if ":" in name)
    for name in shipped:
        r, d = results[name], paired.get(name)
        cells = (
            ["", ""]
            if d is None
            else [
                f"{d['mean']:+.3f}",
                f"[{d['mean'] - d['ci95']:+.3f}, {d['mean'] + d['ci95']:+.3f}]",
            ]
        )
        out.append(f"| `{name}` | {r['mean']:.3f} | {r['ci95']:.3f} | " + " | ".join(cells) + " |")
    if not shipped:
        out.append("| (no shipped policy) | | | | |")
    return [*out, ""]


def changelog_section(env_id: str) -> str | None:
    """The text of ``env_id``'s section of ``CHANGELOG.md`` (``### `id``` under
    ``## Environments``), its links made relative to an env page; ``None`` without one."""
    text = CHANGELOG.read_text(encoding="utf-8")
    envs = re.split(r"^## Environments\s*$", text, maxsplit=1, flags=re.M)
    if len(envs) < 2:
        return None
    envs_text = re.split(r"^## ", envs[1], maxsplit=1, flags=re.M)[0]
    parts = re.split(r"^### (.+?)\s*$", envs_text, flags=re.M)
    for title, body in zip(parts[1::2], parts[2::2], strict=True):
        if title.strip("` ") == env_id:
            # a link relative to the repository's root, from docs/envs/
            return re.sub(r"\]\((?![a-z]+:|#|/)([^)]+)\)", r"](../../\1)", body.strip())
    return None


def env_page(env_id: str) -> str:
    """The MyST page of one registered env id (what ``builder-inited`` writes)."""
    from sensorgym.envs import PARALLEL_ENVS

    spec = _registration(env_id)
    cls = _load(spec.entry_point)
    module = cls.__module__
    intro, sections = _split(inspect.getdoc(cls) or "")
    name = env_name(env_id)

    def roles(text: str, owner: Any = cls) -> str:
        return _roles(text, owner.__module__, owner.__name__, myst=True)

    def ref(c: Any) -> str:
        return f"{{py:class}}`~{c.__module__}.{c.__qualname__}`"

    out = [
        f"# {name}",
        "",
        f"```{{py:currentmodule}} {module}",
        "```",
        "",
        roles(intro),
        "",
        f'![{name}: one seeded episode, frames of render_mode="rgb_array"]'
        f"(../assets/envs/{name}.gif)",
        "",
        f'*One seeded episode (`render_mode="rgb_array"`, every few steps, half size) and, '
        f"below, its last frame at full size, drawn by `python docs/make_pictures.py`, which "
        f"writes `docs/assets/envs/{name}.gif` and `{name}.png`.*",
        "",
        f"![{name}: the last frame of the episode](../assets/envs/{name}.png)",
        "",
        "```python",
        "import gymnasium as gym",
        "import sensorgym.envs  # registers the ids",
        "",
        f'env = gym.make("{env_id}", render_mode="rgb_array")',
        "observation, info = env.reset(seed=0)",
        "```",
        "",
    ]
    bases = [b for b in cls.__mro__[1:] if b.__module__.startswith("sensorgym.envs.")]
    for title in SECTIONS:
        body, owner = sections.get(title), cls
        if body is None and title == "Description":
            mod_intro, _ = _split(inspect.getdoc(importlib.import_module(module)) or "")
            if env_id in mod_intro.split("\n", 1)[0]:
                body, owner = mod_intro.split("\n", 1)[-1].strip(), importlib.import_module(module)
                body = _roles(body, module, None, myst=True)
                out += [f"## {title}", "", body, ""]
                continue
        if body is None and title == "Arguments":
            # the base env's text would name the base's id and params: the same sentence for
            # this id, from the registration
            params = cls.params_type
            out += [
                f"## {title}",
                "",
                f'`gym.make("{env_id}", render_mode=None, **fields)`: every setting is a field '
                f"of {ref(params)} (units in its docstrings), given as a keyword or as "
                f"`params={params.__name__}(...)`; the same keywords work for `gym.make_vec` and "
                "`parallel_env` (below).",
                "",
            ]
            continue
        if body is None:
            for base in bases:
                _, base_sections = _split(inspect.getdoc(base) or "")
                if title in base_sections:
                    body, owner = base_sections[title], base
                    break
        if title == "Version History":
            changes = changelog_section(env_id)
            if body is None and changes is None:
                continue
            out += [f"## {title}", ""]
            if body is not None:
                out += [roles(body, owner), ""]
            out += [
                "### In CHANGELOG.md",
                "",
                "*This env's section of `CHANGELOG.md` (under Environments).*",
                "",
                changes if changes is not None else "No entries.",
                "",
            ]
            continue
        if body is None:
            continue
        out += [f"## {title}", ""]
        if owner is not cls:
            note = f"*From the docstring of {ref(owner)}, which this env keeps"
            if title == "Episode End":
                note += f"; this env's time limit is {spec.max_episode_steps} steps (registration)"
            out += [note + ".*", ""]
        out += [roles(body, owner), ""]
    out += rules_section(env_id) + results_section(env_id)
    out += [
        "## Registration",
        "",
        "| registration | |",
        "|---|---|",
        f"| id | `{env_id}` |",
        f"| entry point | `{spec.entry_point}` |",
        f"| vector entry point | `{spec.vector_entry_point}` |",
        f"| `max_episode_steps` | {spec.max_episode_steps} |",
        f"| params | {ref(cls.params_type)} |",
        "",
        "Registered in {py:mod}`sensorgym.envs`; `gym.make_vec(id, num_envs=N)` builds the "
        "native vector env (every scenario stepped in one batched call).",
        "",
    ]
    factory = PARALLEL_ENVS[env_id]
    pz_module = importlib.import_module(factory.__module__)
    pz_cls = _parallel_class(pz_module, env_id)
    # import the constructors from the env's package when it is their home there
    package = importlib.import_module(pz_module.__name__.rsplit(".", 1)[0])
    if getattr(package, "parallel_env", None) is factory:
        pz_module = package
    pz_intro, pz_sections = _split(inspect.getdoc(pz_cls) or "")
    out += [
        "## PettingZoo",
        "",
        "```python",
        f"from {pz_module.__name__} import env, parallel_env",
        "",
        'parallel = parallel_env(render_mode="rgb_array")  # all agents act at once',
        "observations, infos = parallel.reset(seed=0)",
        "aec = env()  # the AEC form: agents act in turn",
        "```",
        "",
        f"`parallel_env(**fields)` builds {ref(pz_cls)}; `env()` and `raw_env()` wrap it as "
        "PettingZoo AEC envs (with and without PettingZoo's order checks). They take the same "
        "params fields, `max_episode_steps` and `render_mode` as keywords.",
        "",
        _roles(pz_intro, pz_cls.__module__, pz_cls.__name__, myst=True),
        "",
    ]
    for title, body in pz_sections.items():
        out += [f"### {title}", "", _demote(roles(body, pz_cls), 1), ""]
    return "\n".join(line.rstrip() for line in "\n".join(out).splitlines()).rstrip() + "\n"


def index_page(env_ids: list[str]) -> str:
    """The toctree page of the env pages."""
    lines = [
        "# Environment pages",
        "",
        "One page per registered id, generated from the env's docstring (its spec), its "
        "registration and its PettingZoo door. The scores, rules and trained policies of every "
        "env are in [Environments](../environments.md).",
        "",
        "```{toctree}",
        ":maxdepth: 1",
        "",
        *(env_name(i) for i in env_ids),
        "```",
        "",
    ]
    return "\n".join(lines)


def _write(path: Path, text: str) -> None:
    """Write only a changed page, so that an unchanged env does not rebuild."""
    if not path.exists() or path.read_text() != text:
        path.write_text(text)


def write_env_pages(app: Any = None) -> list[Path]:
    """``builder-inited``: (re)write ``docs/envs/`` from the registered ids."""
    from sensorgym.envs import ENV_IDS

    PAGES.mkdir(exist_ok=True)
    written = [PAGES / "index.md"]
    _write(written[0], index_page(ENV_IDS))
    for env_id in ENV_IDS:
        path = PAGES / f"{env_name(env_id)}.md"
        _write(path, env_page(env_id))
        written.append(path)
    for stale in set(PAGES.glob("*.md")) - set(written):
        stale.unlink()
    return written


def copy_html_images(app: Any, exception: Exception | None) -> None:
    """``build-finished``: copy the pictures that pages show through raw HTML
    (``<img src="assets/…">``, kept for GitHub's rendering), which Sphinx does not collect."""
    import shutil

    if exception is not None or app.builder.format != "html":
        return
    src, out = Path(app.srcdir), Path(app.outdir)
    for page in src.rglob("*.md"):
        if out in page.parents or "_build" in page.parts:
            continue
        for ref in re.findall(r'<img [^>]*src="([^":]+)"', page.read_text()):
            image = (page.parent / ref).resolve()
            if image.is_file() and src in image.parents:
                target = out / image.relative_to(src)
                target.parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(image, target)


#: the repository's root Markdown files that a page of the site includes (``{include}``),
#: by the page: a link to one of them in an included text (``[CHANGELOG.md](CHANGELOG.md)`` in
#: README.md) goes to that page
ROOT_FILE_PAGES = {
    "README.md": "index",
    "CHANGELOG.md": "changelog",
    "CONTRIBUTING.md": "contributing",
}


def _root_file_links() -> Any:
    """A post-transform that runs before MyST resolves its links: a link to a root file of
    :data:`ROOT_FILE_PAGES` (which is not a page of the site itself) becomes a link to the
    page that includes it."""
    from sphinx.transforms.post_transforms import SphinxPostTransform

    class RootFileLinks(SphinxPostTransform):
        default_priority = 8  # before myst_parser's MystReferenceResolver (9)

        def run(self, **kwargs: Any) -> None:
            from sphinx import addnodes

            for node in self.document.findall(addnodes.pending_xref):
                if node.get("reftype") != "myst" or node.get("refdomain"):
                    continue
                path, _, anchor = str(node["reftarget"]).partition("#")
                page = ROOT_FILE_PAGES.get(path)
                if page is not None and page in self.env.all_docs:
                    node["refdomain"], node["reftarget"] = "doc", page
                    node["reftargetid"] = anchor or None

    return RootFileLinks


def setup(app: Any) -> dict[str, Any]:
    app.add_post_transform(_root_file_links())
    app.connect("builder-inited", write_env_pages)
    app.connect("build-finished", copy_html_images)
    app.connect("autodoc-process-docstring", process_docstring)
    app.connect("autodoc-process-signature", process_signature)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
