"""The README's first two commands are what CI runs, so they stay true."""

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _readme_commands() -> list[str]:
    lines = (ROOT / "README.md").read_text().splitlines()
    start = lines.index("```bash") + 1
    return lines[start : start + 2]


def test_readme_starts_with_setup_and_test_commands():
    setup, test = _readme_commands()
    assert "pip install torch==2.13.0" in setup
    assert setup.index("torch==2.13.0") < setup.index("pip install -e")
    assert "lanelab-" in setup
    assert "pytest" in test


def test_ci_runs_the_readme_commands_verbatim():
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    setup, test = _readme_commands()
    assert setup in ci
    assert any(line.startswith(test) for line in ci)
