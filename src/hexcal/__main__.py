import os
import sys

try:
    from hexcal.cli import main
except KeyboardInterrupt:  # interrupted while starting: no traceback
    sys.stderr.write("hexcal: interrupted\n")
    os._exit(130)

sys.exit(main())
