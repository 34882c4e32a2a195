"""The reference pages stay in sync with the code: one page per registered id, written from its definition
file, stating its registered keywords and its spaces as ``gym.make`` builds them, the options reference as
the generator writes it now, and the site's navigation over every page; no page over 12 KiB; the examples
of "Make your own" run; CONTRIBUTING.md names what exists."""

from __future__ import annotations

import ast
import importlib.util
import re
import subprocess
import sys
from dataclasses import fields
from pathlib import Path

import gymnasium as gym
import pytest
import yaml
from helpers import ROOT

import emmi_gym
import emmi_gym.tools.cli
from emmi_gym._moved import MOVED
from emmi_gym.env import REWARDS
from emmi_gym.env.definitions import shipped_definitions
from emmi_gym.env.registration import ENV_IDS

DOCS = ROOT / "docs"

gym.register_envs(emmi_gym)


def marked_table(text: str, marker: str) -> list[list[str]]:
    """The body rows of the Markdown table between ``<!-- marker ... -->`` and ``<!-- /marker -->``,
    as lists of cells with their backticks removed."""
    found = re.search(rf"<!-- {marker}\b.*?-->\n(.*?)<!-- /{marker} -->", text, re.S)
    assert found, f"no table marked <!-- {marker} --> ... <!-- /{marker} -->"
    lines = [line.strip() for line in found.group(1).strip().splitlines()]
    assert len(lines) >= 3 and set(lines[1]) <= set("|- "), f"the {marker} block is not a Markdown table"
    rows = []
    for line in lines[2:]:
        cells = [c.strip() for c in line.strip("|").split(" | ")]
        rows.append([c[1:-1] if c.startswith("`") and c.endswith("`") else c for c in cells])
    return rows


def load_generator(name: str = "gen_options_doc"):
    """The docs generator ``docs/_scripts/<name>.py`` as a module."""
    spec = importlib.util.spec_from_file_location(name, ROOT / "docs" / "_scripts" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_marked_tables_are_parsed_as_written():
    text = ("<!-- spaces: x -->\n| space | value |\n| --- | --- |\n| `action_space` | `Discrete(8)` |\n"
            "| `observation_space[\"map\"]` | `Box(0, 255, (2, 64, 64), uint8)` |\n<!-- /spaces -->\n")
    assert marked_table(text, "spaces") == [["action_space", "Discrete(8)"],
                                            ['observation_space["map"]', "Box(0, 255, (2, 64, 64), uint8)"]]
    with pytest.raises(AssertionError):
        marked_table(text, "registered-kwargs")


@pytest.mark.parametrize("name", list(ENV_IDS))
def test_each_id_has_a_page_with_its_registered_keywords(name):
    page = DOCS / "envs" / f"{name}.md"
    assert page.exists(), f"docs/envs/{name}.md is missing"
    text = page.read_text()
    spec = gym.spec(f"emmi_gym/{name}")
    stated = {}
    for row in marked_table(text, "registered-kwargs"):
        assert len(row) == 3 and row[2], f"{page.name}: each keyword needs a value and what it sets: {row}"
        assert row[0] not in stated, f"{page.name}: {row[0]} is listed twice"
        stated[row[0]] = ast.literal_eval(row[1])
    assert stated == spec.kwargs, (f"docs/envs/{name}.md states the keywords {stated}; the registration "
                                   f"(envs/{name}.yaml) sets {spec.kwargs}")
    for heading in ("Description", "Default configuration", "Spaces", "Action space", "Observation space",
                    "Rewards", "Starting state", "Episode end", "Registered id"):
        assert f"\n## {heading}\n" in text, f"{page.name} has no '## {heading}' section"
    assert f"`emmi_gym/{name}`" in text


@pytest.mark.parametrize("name", list(ENV_IDS))
def test_each_page_states_the_spaces_gym_make_builds(name):
    text = (DOCS / "envs" / f"{name}.md").read_text()
    env = gym.make(f"emmi_gym/{name}")
    actual = {"action_space": str(env.action_space)}
    observation = env.observation_space
    if isinstance(observation, gym.spaces.Dict):
        actual.update({f'observation_space["{key}"]': str(space) for key, space in observation.spaces.items()})
    else:
        actual["observation_space"] = str(observation)
    env.close()
    stated = dict(marked_table(text, "spaces"))
    assert stated == actual, f"docs/envs/{name}.md states the spaces {stated}; gym.make builds {actual}"


@pytest.mark.parametrize("name", list(ENV_IDS))
def test_each_env_page_is_what_the_generator_writes_from_its_file_now(name):
    generator = load_generator("gen_env_pages")
    definition = next(d for d in shipped_definitions() if d.id == name)
    expected = generator.render_page(definition, generator.spaces(f"emmi_gym/{name}"))
    assert (DOCS / "envs" / f"{name}.md").read_text() == expected, \
        f"docs/envs/{name}.md is out of date: run `{generator.COMMAND}`"


def test_the_environments_index_table_is_what_the_generator_writes_now():
    generator = load_generator("gen_env_pages")
    text = (DOCS / "envs" / "index.md").read_text()
    assert generator.render_index(text, shipped_definitions()) == text, \
        f"docs/envs/index.md's table is out of date: run `{generator.COMMAND}`"


def test_the_environments_index_links_every_page():
    text = (DOCS / "envs" / "index.md").read_text()
    for name in ENV_IDS:
        assert f"]({name}.md)" in text and f"]({name}.png)" in text, f"docs/envs/index.md lacks {name}"
        assert (DOCS / "envs" / f"{name}.png").exists()


def test_options_reference_is_what_the_generator_writes_now():
    generator = load_generator()
    expected = generator.render()
    actual = (DOCS / "options.md").read_text()
    assert actual == expected, f"docs/options.md is out of date: run `{generator.COMMAND}`"


def test_every_option_has_a_help_line_in_the_reference():
    generator = load_generator()
    text = (DOCS / "options.md").read_text()
    for cls, _ in generator.SECTIONS:
        for f in fields(cls):
            help_text = f.metadata.get("help", "")
            assert help_text and "\n" not in help_text, f"{cls.__name__}.{f.name} has no one-line help="
            assert f"| `{f.name}` |" in text and help_text.replace("|", "\\|") in text


def nav_pages(items) -> list[str]:
    pages = []
    for item in items:
        value = next(iter(item.values())) if isinstance(item, dict) else item
        pages += nav_pages(value) if isinstance(value, list) else [value]
    return pages


def test_the_site_navigation_lists_every_page():
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text())
    listed = nav_pages(config["nav"])
    pages = sorted(str(p.relative_to(DOCS)) for p in DOCS.rglob("*.md"))
    missing = [p for p in pages if p not in listed]
    assert not missing, f"pages not in mkdocs.yml's nav: {missing}"
    gone = [p for p in listed if not (DOCS / p).exists()]
    assert not gone, f"mkdocs.yml's nav lists pages that do not exist: {gone}"


#: Public modules without an API page, and why.
NOT_IN_API = {"emmi_gym.tools.cli": "the command line has its own page, docs/cli.md",
              "emmi_gym.tools.commands": "the command line's subcommands, on docs/cli.md (what they run has API pages)",
              **{old: f"an old name of {new}, documented under it" for old, (new, _) in MOVED.items()}}


def test_every_public_module_has_an_api_page():
    package = ROOT / "emmi_gym"
    modules = {".".join(p.relative_to(ROOT).with_suffix("").parts) for p in package.rglob("*.py")
               if not any(part.startswith("_") for part in p.relative_to(package).parts)}
    documented = set()
    for page in (DOCS / "api").glob("*.md"):
        documented |= set(re.findall(r"^::: ([\w.]+)$", page.read_text(), re.M))
    missing = sorted(m for m in modules - documented if not any(m == n or m.startswith(n + ".") for n in NOT_IN_API))
    assert not missing, f"public modules with no '::: module' line in docs/api/*.md: {missing}"
    packages = {".".join(p.parent.relative_to(ROOT).parts) for p in package.rglob("__init__.py")}
    gone = sorted(name for name in documented
                  if name not in packages and not any(name == m or name.startswith(m + ".") for m in modules))
    assert not gone, f"docs/api/*.md documents modules that do not exist: {gone}"


def test_the_rewards_page_states_every_registered_reward_with_what_it_reads_and_its_scale():
    text = (DOCS / "rewards.md").read_text()
    for name, reward in REWARDS.items():
        row = re.search(rf'^\| `"{name}"`(?: \(default\))? \| ([^|]+) \|.*\| ([^|]+) \|$', text, re.M)
        assert row, f'docs/rewards.md has no row for the reward "{name}"'
        reads = "ground truth (privileged)" if reward.privileged else "filter"
        assert row.group(1) == reads, f"docs/rewards.md: {name} reads the {reads}"
        assert float(row.group(2)) == reward.scale, f"docs/rewards.md: {name}'s scale is {reward.scale:g}"


def test_the_info_page_states_every_key():
    env = gym.make("emmi_gym/ExploreVelocity-v0", update_records=True)
    _, info = env.reset(seed=0)
    keys = set(info) | set(env.step(env.action_space.sample())[4]) | {"target_kind"}
    env.close()
    text = (DOCS / "info.md").read_text()
    missing = sorted(key for key in keys if f"| `{key}` |" not in text)
    assert not missing, f"docs/info.md does not state the info keys {missing}"


#: The largest a docs page may be, in bytes of its Markdown with the files it includes: a page is read
#: as a reference, so a longer one is split by topic (as the benchmarks are, one page per topic).
MAX_PAGE_BYTES = 12 * 1024
#: A pymdownx.snippets line, which includes a file (relative to the repository root) into the page.
SNIPPET = re.compile(r'^--8<-- "([^"]+)"$', re.M)


def included_bytes(name: str) -> int:
    """The bytes a snippet line includes: a whole file (``FILE``), or the lines of one section (``FILE:NAME``,
    between the file's ``--8<-- [start:NAME]`` and ``--8<-- [end:NAME]`` markers, as pymdownx.snippets cuts it)."""
    path, _, section = name.partition(":")
    data = (ROOT / path).read_bytes()
    if not section:
        return len(data)
    found = re.search(rf"--8<-- \[start:{re.escape(section)}\][^\n]*\n(.*?)\n[^\n]*--8<-- \[end:{re.escape(section)}\]",
                      data.decode(), re.S)
    assert found, f"{path} has no section {section!r}"
    return len(found.group(1).encode())


def page_bytes(page: Path) -> int:
    """The size of ``page`` as the site renders it: its own bytes plus those of the files it includes."""
    text = page.read_text()
    included = sum(included_bytes(name) for name in SNIPPET.findall(text))
    return len(SNIPPET.sub("", text).encode()) + included


def test_page_size_counts_included_files(tmp_path):
    page = tmp_path / "page.md"
    page.write_text('# Changes\n\n--8<-- "CHANGELOG.md"\n')
    assert page_bytes(page) == len(b"# Changes\n\n\n") + len((ROOT / "CHANGELOG.md").read_bytes())
    page.write_text('# Changes\n\n--8<-- "CHANGELOG.md:release-0-1-0"\n')
    section = (ROOT / "CHANGELOG.md").read_text().split("## 0.1.0\n")[1].rsplit("\n<!--", 1)[0]
    assert page_bytes(page) == len(b"# Changes\n\n\n") + len(("## 0.1.0\n" + section).encode())


def test_no_docs_page_exceeds_12_kib():
    sizes = {str(p.relative_to(DOCS)): page_bytes(p) for p in DOCS.rglob("*.md")}
    too_large = {name: size for name, size in sorted(sizes.items()) if size > MAX_PAGE_BYTES}
    assert not too_large, (f"docs pages over {MAX_PAGE_BYTES} bytes: {too_large}; split them by topic "
                           "(see docs/results/) or move figures to the results pages")


#: The worked examples of docs/make_your_own.md, in the page's order.
EXAMPLES = ("reward", "action", "observation", "world", "env_file")


def marked_block(text: str, opening: str, closing: str, language: str) -> str:
    """The fenced ``language`` block between ``<!-- opening -->`` and ``<!-- closing -->``."""
    found = re.search(rf"<!-- {re.escape(opening)} -->\n```{language}\n(.*?)```\n<!-- {re.escape(closing)} -->",
                      text, re.S)
    assert found, f"no {language} block marked <!-- {opening} --> ... <!-- {closing} -->"
    return found.group(1)


def example_code(name: str) -> str:
    return marked_block((DOCS / "make_your_own.md").read_text(), f"example: {name}", "/example", "python")


def test_the_marked_blocks_are_parsed_as_written():
    text = "<!-- example: reward -->\n```python\nx = 1\n```\n<!-- /example -->\n"
    assert marked_block(text, "example: reward", "/example", "python") == "x = 1\n"
    with pytest.raises(AssertionError):
        marked_block(text, "example: world", "/example", "python")
    with pytest.raises(AssertionError):
        marked_block(text, "example: reward", "/example", "bash")


def test_make_your_own_has_its_five_examples():
    text = (DOCS / "make_your_own.md").read_text()
    assert tuple(re.findall(r"<!-- example: (\w+) -->", text)) == EXAMPLES


@pytest.fixture
def restore_registry():
    """The Gymnasium registry and the rewards' as they were: an example that registers an id or a reward leaves
    nothing behind."""
    before, rewards = set(gym.registry), dict(REWARDS)
    yield
    for env_id in set(gym.registry) - before:
        del gym.registry[env_id]
    REWARDS.clear()
    REWARDS.update(rewards)


@pytest.mark.parametrize("name", EXAMPLES)
def test_each_make_your_own_example_runs(name, tmp_path, monkeypatch, restore_registry):
    code = example_code(name)
    monkeypatch.chdir(tmp_path)  # the world example writes its world file here
    exec(compile(code, f"docs/make_your_own.md ({name} example)", "exec"), {"__name__": f"make_your_own_{name}"})


def test_contributing_sets_up_with_the_readme_test_command():
    setup = marked_block((ROOT / "CONTRIBUTING.md").read_text(), "setup-command", "/setup-command", "bash")
    test = marked_block((ROOT / "README.md").read_text(), "test-command", "/test-command", "bash")
    assert setup == test, "CONTRIBUTING.md's set-up line differs from the README's test command"


def test_contributing_names_files_commands_and_markers_that_exist(pytestconfig):
    text = (ROOT / "CONTRIBUTING.md").read_text()
    paths = set(re.findall(r"\b((?:scripts|measurements|tests|docs)/[\w./-]+\.(?:py|md))\b", text))
    paths |= set(re.findall(r"\]\(([^)#:]+)(?:#[^)]*)?\)", text))
    missing = sorted(p for p in paths if not (ROOT / p).exists())
    missing += sorted(name for name in re.findall(r"`(\w+\.py)`", text)
                      if not any((ROOT / folder / name).exists() for folder in ("scripts", "measurements")))
    assert not missing, f"CONTRIBUTING.md names files that do not exist: {missing}"
    parser = emmi_gym.tools.cli.build_parser()
    for command in sorted(set(re.findall(r"`emmi-gym (\w+)", text))):
        with pytest.raises(SystemExit) as done:
            parser.parse_args([command, "--help"])
        assert done.value.code == 0, f"CONTRIBUTING.md names `emmi-gym {command}`, which is not a subcommand"
    markers = [line.split(":")[0] for line in pytestconfig.getini("markers")]
    assert "slow" in markers and "@pytest.mark.slow" in text, "CONTRIBUTING.md's slow marker is not pytest's"


@pytest.mark.slow
@pytest.mark.parametrize("page", ["README.md", "docs/training.md"])
def test_the_pretrained_agents_snippets_run_as_written_in_a_fresh_interpreter(page):
    """What a new user copies: ``import emmi_gym`` alone must make ``emmi_gym.pretrained`` available."""
    blocks = [block for block in re.findall(r"```python\n(.*?)```", (ROOT / page).read_text(), re.S)
              if "emmi_gym.pretrained" in block]
    assert blocks, f"{page} shows no snippet of emmi_gym.pretrained"
    for block in blocks:
        done = subprocess.run([sys.executable, "-c", block], capture_output=True, text=True, timeout=600, cwd=ROOT)
        assert done.returncode == 0, f"{page}'s snippet fails:\n{block}\n{done.stderr[-2000:]}"


def test_the_cli_page_lists_every_subcommand():
    parser = emmi_gym.tools.cli.build_parser()
    commands = set(re.search(r"\{([\w,-]+)\}", parser.format_usage()).group(1).split(","))
    listed = set(re.findall(r"^\| `emmi-gym ([\w-]+)", (DOCS / "cli.md").read_text(), re.MULTILINE))
    assert listed == commands, f"docs/cli.md lists {sorted(listed - commands)} and lacks {sorted(commands - listed)}"


def test_no_user_page_runs_a_maintainer_script():
    """What users are told to run is installed with the package (an ``emmi-gym`` subcommand) or a benchmark;
    scripts/ holds the maintainers' tools, which CONTRIBUTING.md names."""
    pages = [ROOT / "README.md", *DOCS.rglob("*.md")]
    runs = [f"{page.relative_to(ROOT)}: {line.strip()}" for page in pages for line in page.read_text().splitlines()
            if re.search(r"python3? (?:\./)?scripts/", line)]
    assert not runs, f"user pages run files of scripts/: {runs}"


def test_the_measurements_index_lists_every_script_and_the_pages_that_cite_it():
    index = (ROOT / "measurements" / "README.md").read_text()
    listed = dict(re.findall(r"^\| `(\w+\.py)` \| .* \| (.+) \|$", index, re.MULTILINE))
    scripts = {p.name for p in (ROOT / "measurements").glob("*.py") if not p.name.startswith("_")}
    assert set(listed) == scripts, f"measurements/README.md lists {sorted(set(listed) - scripts)}, " \
                                   f"lacks {sorted(scripts - set(listed))}"
    for script, cited_by in listed.items():
        pages = re.findall(r"\]\(\.\./(docs/[\w/.-]+\.md)", cited_by)
        assert pages and all((ROOT / page).exists() for page in pages), f"{script}: cited by {cited_by}"
        assert all(script in (ROOT / page).read_text() for page in pages), f"{script}: not on all of {pages}"
