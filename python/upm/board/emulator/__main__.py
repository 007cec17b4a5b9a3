"""``python -m upm.board.emulator``: a board emulator in its own process (:func:`upm.board.process.main`)."""

import sys

from ..process import main

sys.exit(main())
