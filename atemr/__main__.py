import sys

from atemr.cli.main import main

if __name__ == "__main__":  # a spawned process (the recording's writer) imports this module without running it
    sys.exit(main())
