"""``python -m vsj``: the ``vsj`` command."""

import sys

from .cli import main

# guarded so that tools which import every module (the API reference's generator) do
# not run the command
if __name__ == "__main__":
    sys.exit(main())
