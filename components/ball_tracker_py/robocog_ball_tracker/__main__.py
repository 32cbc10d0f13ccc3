"""`python -m robocog_ball_tracker [FLAGS...]`: the tracker, as `python -m robocog run
robocog_ball_tracker` (the launcher's way) runs it."""

import sys

from robocog.component import main

from . import BallTrackerComponent

if __name__ == "__main__":
    sys.exit(main(BallTrackerComponent))
