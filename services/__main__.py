"""`python -m hamnet` is the `hamnet` command."""

import sys

from hamnet.cli import main

sys.exit(main())
