"""``python -m sim_table``: run the table emulator (see :mod:`sim_table.process`); ``--help`` (and ``--help-json``,
the options as one JSON object for ``rig emulate --help``) from :mod:`sim_table.options` alone (the models are
loaded only to run)."""

import sys

if "--help-json" in sys.argv[1:]:
    import json

    from sim_table.options import describe

    print(json.dumps(describe()))
    sys.exit(0)
if {"-h", "--help"} & set(sys.argv[1:]):
    from sim_table.options import argument_parser

    argument_parser().parse_args(["--help"])

from sim_table.process import main

sys.exit(main())
