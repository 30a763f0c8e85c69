"""``atemr fuzzy``: evaluate a fuzzy engine on rows from stdin, or print and plot it.

``atemr fuzzy eval ENGINE`` reads rows of input values (whitespace- or comma-separated; an optional first
line naming the inputs, in any order) and prints, like fuzzylite's `.fld` export, a header with the input
and output names and one row per input row: the inputs, then the outputs. ENGINE is a ``.yaml``/``.fll``
file or a shipped engine name (``idle``, ``manual``).
"""

from __future__ import annotations

import argparse
import math
import re
import sys
from pathlib import Path
from typing import TYPE_CHECKING, TextIO

if TYPE_CHECKING:  # only what runs a command imports what it needs: `atemr --help` stays fast
    import numpy as np

    from atemr.skills.fuzzy.engine import Engine, InputVariable, OutputVariable

from atemr.errors import ConfigError

_SPLIT = re.compile(r"[,\s]+")


def _fmt(v: float) -> str:
    if math.isnan(v):
        return "nan"
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    return f"{v:.9f}"


def _is_number(word: str) -> bool:
    try:
        float(word)
    except ValueError:
        return False
    return True


def read_rows(engine: Engine, stream: TextIO, name: str = "stdin") -> tuple[list[str], np.ndarray]:
    """Parse the input table: (column names in engine order, array rows × inputs); bad lines raise
    `ConfigError` naming the line."""
    import numpy as np

    names = list(engine.input_names)
    order = list(range(len(names)))
    rows: list[list[float]] = []
    seen_data = False
    for number, raw in enumerate(stream, 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        words = [w for w in _SPLIT.split(line) if w]
        if not seen_data and not any(_is_number(w) for w in words):
            unknown = [w for w in words if w not in names]
            if unknown or len(set(words)) != len(words) or len(words) != len(names):
                raise ConfigError(
                    f"header must name each input once ({' '.join(names)}); got {' '.join(words)}",
                    file=name, line=number,
                )
            order = [words.index(n) for n in names]
            seen_data = True
            continue
        seen_data = True
        if len(words) != len(names):
            raise ConfigError(f"expected {len(names)} values ({' '.join(names)}), got {len(words)}",
                              file=name, line=number)
        try:
            values = [float(w) for w in words]
        except ValueError:
            bad = next(w for w in words if not _is_number(w))
            raise ConfigError(f"'{bad}' is not a number", file=name, line=number) from None
        rows.append([values[i] for i in order])
    return names, np.asarray(rows, dtype=np.float64).reshape(-1, len(names))


def evaluate_table(engine: Engine, stream: TextIO, out: TextIO, name: str = "stdin") -> int:
    """Read rows from ``stream``, write the `.fld`-style table to ``out``; returns the number of rows."""
    names, data = read_rows(engine, stream, name)
    result = engine.process({n: data[:, i] for i, n in enumerate(names)})
    out.write(" ".join([*names, *engine.output_names]) + "\n")
    columns = [data[:, i] for i in range(len(names))] + [result[n] for n in engine.output_names]
    for r in range(data.shape[0]):
        out.write(" ".join(_fmt(float(c[r])) for c in columns) + "\n")
    return int(data.shape[0])


def plot_engine(engine: Engine, path: Path, points: int = 501) -> None:
    """Draw every variable's membership functions into one PNG (needs matplotlib, imported lazily)."""
    import numpy as np

    from atemr.skills.fuzzy.engine import InputVariable

    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise ConfigError("plotting needs matplotlib (pip install matplotlib)") from None
    variables: list[InputVariable | OutputVariable] = [*engine.inputs, *engine.outputs]
    cols = 2
    rows = (len(variables) + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(10, 2.6 * rows), squeeze=False)
    for ax, var in zip(axes.flat, variables, strict=False):
        x = np.linspace(var.minimum, var.maximum, points)
        for term in var.terms:
            if term.kind == "Linear":
                continue
            ax.plot(x, term.membership(x), label=f"{term.name} ({term.kind})")
        role = "input" if isinstance(var, InputVariable) else "output"
        ax.set_title(f"{var.name} ({role})")
        ax.set_ylim(-0.05, 1.05)
        ax.legend(fontsize="small")
    for ax in list(axes.flat)[len(variables):]:
        ax.set_visible(False)
    fig.suptitle(f"{engine.name}: membership functions")
    fig.tight_layout()
    try:
        fig.savefig(path, dpi=90)
    except OSError as exc:
        raise ConfigError(f"cannot write the plot: {exc.strerror}", file=str(path)) from None
    finally:
        plt.close(fig)


class FuzzyCommand:
    def configure(self, parser: argparse.ArgumentParser) -> None:
        sub = parser.add_subparsers(dest="fuzzy_action", metavar="ACTION", required=True)
        ev = sub.add_parser("eval", help="read input rows on stdin, print inputs and outputs like a .fld")
        ev.add_argument("engine", metavar="ENGINE", help="a .yaml or .fll engine, or a shipped name (idle, manual)")
        ev.add_argument("--input", type=Path, help="read rows from this file instead of stdin")
        sh = sub.add_parser("show", help="print the engine; optionally plot its membership functions")
        sh.add_argument("engine", metavar="ENGINE", help="a .yaml or .fll engine, or a shipped name (idle, manual)")
        sh.add_argument("--plot", type=Path, metavar="PNG", help="write the membership functions to this PNG")

    def run(self, args: argparse.Namespace) -> int:
        from atemr.skills.fuzzy.loader import resolve_engine

        engine = resolve_engine(args.engine)
        if args.fuzzy_action == "eval":
            if args.input is not None:
                try:
                    with args.input.open(encoding="utf-8") as stream:
                        evaluate_table(engine, stream, sys.stdout, str(args.input))
                except FileNotFoundError:
                    raise ConfigError("file not found", file=str(args.input)) from None
            else:
                evaluate_table(engine, sys.stdin, sys.stdout)
            return 0
        sys.stdout.write(engine.describe())
        if args.plot is not None:
            plot_engine(engine, args.plot)
            print(f"plot written to {args.plot}")
        return 0
