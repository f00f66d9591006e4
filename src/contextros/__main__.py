import sys

from contextros.cli import main

sys.exit(main())
