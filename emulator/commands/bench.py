"""``rowtrack bench``: run the registered benchmarks and report measured figures."""

import json
import os
import sys
from contextlib import contextmanager, redirect_stdout
from pathlib import Path

from emulator.cli import UsageError

NAME = "bench"
HELP = "run benchmarks (simulation, synthesis) and report the measured figures"


def add_arguments(parser):
    parser.add_argument("--only", action="append", metavar="NAME",
                        help="run only this benchmark (repeatable); see --list")
    parser.add_argument("--json", action="store_true",
                        help="print one flat JSON object of figures with dotted keys")
    parser.add_argument("--write-docs", type=Path, metavar="DIR",
                        help="also write DIR/<name>.md and DIR/figures.json")
    parser.add_argument("--render-docs", type=Path, metavar="DIR",
                        help="measure nothing: rewrite DIR/<name>.md from the figures in "
                             "DIR/figures.json (after a change to a page's text), keeping "
                             "each page's measurement line")
    parser.add_argument("--list", action="store_true", help="list the benchmarks and exit")
    parser.add_argument("--jobs", type=int, default=1, metavar="N",
                        help="processes for the benchmarks made of independent runs "
                             "(hw_tracking); the figures do not depend on it (default 1)")


def run(args):
    from emulator import bench
    if args.list:
        print("\n".join(bench.names()))
        return 0
    selected = args.only or bench.names()
    unknown = [name for name in selected if name not in bench.BENCHES]
    if unknown:
        raise UsageError(f"unknown benchmark {unknown[0]!r}; "
                         f"benchmarks are: {', '.join(bench.names())}")
    if args.jobs < 1:
        raise UsageError(f"--jobs must be at least 1, not {args.jobs}")
    if args.render_docs:
        return _render_docs(bench, args.render_docs, selected)
    figures = {}
    with _stdout_to_stderr():
        for name in selected:
            print(f"[bench] {name} ...", file=sys.stderr, flush=True)
            figures.update(bench.measure(name, args.jobs))
    if args.write_docs:
        args.write_docs.mkdir(parents=True, exist_ok=True)
        for name in selected:
            (args.write_docs / f"{name}.md").write_text(bench.report(name, figures))
        merged_path = args.write_docs / "figures.json"
        merged = json.loads(merged_path.read_text()) if merged_path.exists() else {}
        # A re-measured benchmark's figures replace all of its old ones: a figure it no
        # longer reports must not linger.
        merged = {key: value for key, value in merged.items()
                  if not any(bench.owns(name, key) for name in selected)}
        merged.update(figures)
        merged_path.write_text(json.dumps(dict(sorted(merged.items())), indent=2) + "\n")
        print(f"[bench] wrote {args.write_docs}/", file=sys.stderr)
    if args.json:
        print(json.dumps(figures, sort_keys=True))
    else:
        width = max((len(k) for k in figures), default=0)
        for key, value in sorted(figures.items()):
            print(f"{key:<{width}}  {value}")
    return 0


@contextmanager
def _stdout_to_stderr():
    """While the benchmarks run, everything written to standard output — by Python or by
    the simulators and compilers they start — goes to standard error, so that standard
    output carries the figures alone (``--json`` can be piped into a parser)."""
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        os.dup2(2, 1)
        with redirect_stdout(sys.stderr):
            yield
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)


def _render_docs(bench, out, selected):
    """Rewrite the pages of ``selected`` benchmarks from ``out/figures.json``."""
    path = out / "figures.json"
    if not path.exists():
        raise UsageError(f"--render-docs {out}: there is no {path} to render from")
    figures = json.loads(path.read_text())
    for name in selected:
        page = out / f"{name}.md"
        measured = bench.page_measured_line(page.read_text()) if page.exists() else None
        if measured is None:
            raise UsageError(f"--render-docs: {page} has no measurement line; measure it "
                             f"with `rowtrack bench --only {name} --write-docs {out}`")
        page.write_text(bench.report(name, figures, measured))
    print(f"[bench] rendered {', '.join(selected)} in {out}/", file=sys.stderr)
    return 0
