"""Write the README's measured figures from `benchmarks/results/*.json`, as the docs hook does for the pages.

    .venv/bin/python scripts/readme_figures.py            # rewrite README.md's marked blocks
    .venv/bin/python scripts/readme_figures.py --check    # exit 1 if README.md differs from what the results render

GitHub shows the README as it is, not built, so its figures are written into it: each block
between `<!-- figures LABEL` TEMPLATE `end of figures LABEL -->` and `<!-- /figures LABEL -->` is
TEMPLATE with its `{{ result: NAME key }}` values filled in, and each `<!-- results: NAME KEY -->` ...
`<!-- /results -->` block is that table (docs/hooks/results.py). Edit the template or the
results file, never the rendered text: tests/test_docs.py fails when they disagree.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs" / "hooks"))

from results import ResultsError, render_readme, results_dir  # noqa: E402

from renderloop.io.atomic import write_text  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true", help="only check; exit 1 when README.md is not what the results render")
    parser.add_argument("--readme", type=Path, default=ROOT / "README.md")
    args = parser.parse_args()
    try:
        text = args.readme.read_text(encoding="utf-8")
        rendered = render_readme(text, results_dir(ROOT), args.readme.name)
    except (OSError, ResultsError) as error:
        print(f"readme_figures: {error}", file=sys.stderr)
        return 2
    if rendered == text:
        return 0
    if args.check:
        print(f"readme_figures: {args.readme} differs from what benchmarks/results renders: "
              f"run .venv/bin/python scripts/readme_figures.py", file=sys.stderr)
        return 1
    write_text(args.readme, rendered)
    print(f"readme_figures: wrote {args.readme}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
