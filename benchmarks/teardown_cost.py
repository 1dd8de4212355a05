"""What ``phri``'s exit through ``os._exit`` saves: the same command with the interpreter's
usual teardown instead (``--teardown``). Run from the repository root, e.g.

    python -m benchmarks.teardown_cost simulate configs/harmony_upper_arm.yaml \\
        examples/wrench_log.csv -o /tmp/forces.csv -q
    python -m benchmarks.teardown_cost --teardown simulate ...   (the same arguments)

and time both whole processes (benchmarks/STARTUP.md gives the figures and the command).
"""

import os
import sys

if __name__ == "__main__":
    args = sys.argv[1:]
    if args[:1] == ["--teardown"]:
        args = args[1:]
        os._exit = sys.exit        # phri_cli.main.main then leaves through SystemExit
    from phri_cli.main import main

    main(args)
