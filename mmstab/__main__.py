import sys

from mmstab.cli import main

sys.exit(main())
