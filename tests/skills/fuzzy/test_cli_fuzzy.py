"""``atemr fuzzy eval`` and ``atemr fuzzy show``."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest

from atemr.cli.main import main
from atemr.skills.fuzzy import load_builtin_engine

ENGINE = """\
name: half
inputs:
  a: {range: [0.0, 1.0], terms: {LOW: Ramp 1 0, HIGH: Ramp 0 1}}
  b: {range: [0.0, 1.0], terms: {LOW: Ramp 1 0, HIGH: Ramp 0 1}}
outputs:
  y: {range: [0.0, 1.0], defuzzifier: WeightedAverage TakagiSugeno, terms: {ONE: Constant 1, ZERO: Constant 0}}
rule_blocks:
  - conjunction: Minimum
    rules: [if a is HIGH and b is HIGH then y is ONE, if a is LOW then y is ZERO]
"""


@pytest.fixture
def engine_file(tmp_path: Path) -> Path:
    path = tmp_path / "half.yaml"
    path.write_text(ENGINE)
    return path


def run(args: list[str], stdin: str, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
        ) -> tuple[int, str, str]:
    monkeypatch.setattr("sys.stdin", io.StringIO(stdin))
    code = main(args)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_eval_without_header(engine_file: Path, monkeypatch: pytest.MonkeyPatch,
                             capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(["fuzzy", "eval", str(engine_file)], "1 1\n0.5, 0.5\n\n0 1\n", monkeypatch, capsys)
    assert code == 0
    lines = out.splitlines()
    assert lines[0] == "a b y"
    # (1,1): only ONE fires → 1; (.5,.5): ONE .5, ZERO .5 → .5; (0,1): only ZERO → 0
    assert lines[1:] == ["1.000000000 1.000000000 1.000000000", "0.500000000 0.500000000 0.500000000",
                         "0.000000000 1.000000000 0.000000000"]


def test_eval_with_header_in_another_order(engine_file: Path, monkeypatch: pytest.MonkeyPatch,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(["fuzzy", "eval", str(engine_file)], "b,a\n1,0\n", monkeypatch, capsys)
    assert code == 0
    assert out.splitlines() == ["a b y", "0.000000000 1.000000000 0.000000000"]


def test_eval_prints_nan_when_no_rule_fires(engine_file: Path, monkeypatch: pytest.MonkeyPatch,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    _, out, _ = run(["fuzzy", "eval", str(engine_file)], "1 0\n", monkeypatch, capsys)
    assert out.splitlines()[1] == "1.000000000 0.000000000 nan"


@pytest.mark.parametrize(
    ("stdin", "why"),
    [
        ("0.1 0.2\n0.3\n", "stdin:2: expected 2 values (a b), got 1"),
        ("a b\n0.1 0.2\n\n0.1 high\n", "stdin:4: 'high' is not a number"),
        ("a c\n0.1 0.2\n", "stdin:1: header must name each input once"),
    ],
)
def test_eval_bad_rows_name_the_line(engine_file: Path, monkeypatch: pytest.MonkeyPatch,
                                     capsys: pytest.CaptureFixture[str], stdin: str, why: str) -> None:
    code, out, err = run(["fuzzy", "eval", str(engine_file)], stdin, monkeypatch, capsys)
    assert code == 2
    assert why in err
    assert out == ""


def test_eval_builtin_engine_matches_the_api(monkeypatch: pytest.MonkeyPatch,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    rows = "FR FL LC RL RR RC\n0.4 1.2 1.2 1.2 1.2 1.2\n1.2 1.2 1.2 0.5 0.5 1.2\n"
    code, out, _ = run(["fuzzy", "eval", "idle"], rows, monkeypatch, capsys)
    assert code == 0
    table = np.array([[float(v) for v in line.split()] for line in out.splitlines()[1:]])
    engine = load_builtin_engine("idle")
    expected = engine.process({n: table[:, i] for i, n in enumerate(engine.input_names)})
    np.testing.assert_allclose(table[:, 6], expected["linSteer"], atol=1e-9)
    np.testing.assert_allclose(table[:, 7], expected["angSteer"], atol=1e-9)


def test_eval_reads_an_fll_engine_from_shared(shared_dir: Path, monkeypatch: pytest.MonkeyPatch,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    fll = shared_dir / "reference" / "fuzzylite" / "mamdani_SimpleDimmer.fll"
    if not fll.is_file():
        pytest.skip(f"{fll} is absent")
    code, out, _ = run(["fuzzy", "eval", str(fll)], "0\n0.5\n", monkeypatch, capsys)
    assert code == 0
    assert out.splitlines() == ["Ambient Power", "0.000000000 nan", "0.500000000 0.500000000"]


def test_show_prints_and_plots(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                               capsys: pytest.CaptureFixture[str]) -> None:
    png = tmp_path / "manual.png"
    code, out, _ = run(["fuzzy", "show", "manual", "--plot", str(png)], "", monkeypatch, capsys)
    assert code == 0
    assert "Engine: MANUAL" in out and "OutputVariable: fwdSteer" in out and out.count("rule:") == 13
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_unknown_engine_is_a_clear_error(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(["fuzzy", "show", "nowhere.yaml"], "", monkeypatch, capsys)
    assert code == 2 and "nowhere.yaml: file not found" in err
