"""The README's set-up commands stay true."""

import re

from .conftest import ROOT


def _commands():
    return re.findall(r"```bash\n(.+?)\n```", (ROOT / "README.md").read_text())


def test_two_setup_commands():
    cmds = _commands()
    assert "servo-toolkit report" in cmds[0]
    assert "pytest" in cmds[1] and ".[test]" in cmds[1]


def test_ci_runs_the_readme_test_command():
    assert _commands()[1] in (ROOT / ".ci" / "run").read_text()


def test_a_notebooks_extra_executes_the_notebooks_and_the_readme_names_it():
    import tomllib
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    names = {re.split(r"[<>=\[ ]", req)[0] for req in extras["notebooks"]}
    assert {"nbconvert", "ipykernel", "nbmake", "ipywidgets", "dask"} <= names
    assert '".[notebooks]"' in (ROOT / "README.md").read_text()


def test_the_readme_stays_under_12_kb():
    assert len((ROOT / "README.md").read_bytes()) < 12_000
