"""The learning benchmark's bookkeeping: curves from the CSV log, the Markdown, RESULTS.md."""

import importlib.util
import math
from pathlib import Path

BENCH = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_learning.py"
spec = importlib.util.spec_from_file_location("bench_learning", BENCH)
bench = importlib.util.module_from_spec(spec)
spec.loader.exec_module(bench)


def test_curves_come_from_the_logged_rows_and_skip_empty_cells(tmp_path: Path):
    log = tmp_path / "metrics.csv"
    log.write_text("epoch,step,train/loss,train/loss_reg,val/f1,lr\n0,9,5.0,2.0,,0.1\n0,19,4.0,1.5,,0.1\n0,19,,,0.25,\n")
    curves = bench.read_curves(log)
    assert curves == {"train/loss": ([9, 19], [5.0, 4.0]), "train/loss_reg": ([9, 19], [2.0, 1.5]),
                      "val/f1": ([19], [0.25])}  # fmt: skip


def run(model: str, seed: int, f1: float) -> dict:
    scores = {key: 0.5 for key in bench.SCORES} | {"f1": f1}
    return {"model": model, "seed": seed, "seconds": 120.0, "steps": 100, "heldout": scores,
            "blind_prior": {key: 0.4 for key in bench.SCORES}, "curves": {}}  # fmt: skip


def test_the_report_gives_mean_and_spread_over_seeds_the_prior_and_the_lead():
    runs = {f"{m} s{s}": run(m, s, f1) for m, s, f1 in [("a", 0, 0.6), ("a", 1, 0.7), ("b", 0, 0.5), ("b", 1, 0.5)]}
    markdown = bench.report({"command": "python x", "machine": "here", "runs": runs}, ["a", "b"], "c.png")
    assert markdown.startswith(bench.SECTION)
    assert "| **a** | mean ± std |  |  | 65.0 ± 7.1 |" in markdown
    assert "| blind prior | – | – | – | 40.0 |" in markdown
    lead = 100 * math.hypot(math.sqrt(0.005), 0.0)
    assert f"a leads b by +15.0 ± {lead:.1f} F1 points" in markdown
    assert "![learning curves](c.png)" in markdown


def test_the_section_replaces_its_old_self_and_nothing_else():
    results = "# Results\n\n## A\n\nold a\n\n" + bench.SECTION + "\n\nold numbers\n\n## B\n\nb\n"
    replaced = bench.replace_section(results, bench.SECTION + "\n\nnew numbers\n")
    assert "new numbers" in replaced and "old numbers" not in replaced
    assert replaced.startswith("# Results\n\n## A\n\nold a\n\n") and replaced.endswith("## B\n\nb\n")
    assert bench.replace_section("# Results\n", "X\n") == "# Results\n\nX\n"


def budget(f1: float, missed: float) -> dict:
    """An error budget with every fix at the predictions' F1 but "missed lanes"."""
    fixes = ["as predicted", "near positions", "far positions", "positions", "extents", "missed lanes", "false lanes"]
    return {fix: {"f1": missed if fix == "missed lanes" else f1} for fix in fixes}


def test_the_report_says_where_each_models_f1_goes_beside_the_prior():
    runs = {f"a s{s}": run("a", s, f1) | {"budget": budget(f1, f1 + gain), "prior_budget": budget(0.4, 0.5)}
            for s, f1, gain in [(0, 0.6, 0.1), (1, 0.7, 0.2)]}  # fmt: skip
    markdown = bench.report({"command": "python x", "machine": "here", "runs": runs}, ["a"], "c.png")
    assert "Where the held-out F1 goes" in markdown
    assert "| a | 65.0 ± 7.1 | +0.0 ± 0.0 |" in markdown and "| +15.0 ± 7.1 | +0.0 ± 0.0 |" in markdown
    assert "| blind prior | 40.0 | +0.0 |" in markdown and "| +10.0 | +0.0 |" in markdown
    without = {label: {k: v for k, v in r.items() if k not in ("budget", "prior_budget")} for label, r in runs.items()}
    assert "Where the held-out F1 goes" not in bench.report({"command": "x", "machine": "y", "runs": without}, ["a"], "c.png")
