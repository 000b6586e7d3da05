import sys

from imupipe.cli import main

sys.exit(main())
