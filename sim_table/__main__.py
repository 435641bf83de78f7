"""``python -m sim_table``: run the table emulator (see :mod:`sim_table.process`)."""

import sys

from sim_table.process import main

sys.exit(main())
