import sys

from hexcal.cli import main

sys.exit(main())
