"""``pano2cad batch INPUTS --out DIR``: ``pano2cad run`` on many panoramas, resumable, into DIR/<name>/.

Exit codes: 0 every item succeeded (or was already complete), 3 some items
failed (recorded in DIR/index.csv), 2 bad usage, 1 internal error.
"""

from __future__ import annotations

from .outdir import prepare_out_dir
from .progress import Progress


def run(args) -> int:
    from .batch import EXIT_SOME_FAILED, discover_inputs, run_batch
    from .cmd_run import check_options, options_from_args
    from .errors import UserError

    check_options(args)
    if args.scheduler and args.engine != "dask":
        raise UserError("--scheduler needs --engine dask")
    if args.jobs < 0:
        raise UserError(f"--jobs: expected 0 (one per core) or more, got {args.jobs}")
    items = discover_inputs(args.inputs)
    out = prepare_out_dir(args.out)
    prog = Progress(args.quiet)
    result = run_batch(items, out, options_from_args(args), size=args.size, force=args.force,
                       engine=args.engine, scheduler=args.scheduler, jobs=args.jobs, progress=prog)
    prog.say(f"batch: {result.count('ok')} computed, {result.count('skipped')} skipped, "
             f"{len(result.failed)} failed of {len(result.results)} in {result.seconds:.1f} s")
    print(result.index_csv)
    if result.index_parquet is not None:
        print(result.index_parquet)
    return EXIT_SOME_FAILED if result.failed else 0
