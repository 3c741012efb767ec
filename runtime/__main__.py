"""``python -m dtdyn ...``: the `dtdyn` command (`dtdyn.app.main`)."""
import sys

from dtdyn.app import main

sys.exit(main())
