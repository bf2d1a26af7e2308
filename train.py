"""Train a stable-baselines3 agent on an ActiveLoc env: ``python train.py --help``.

The same as ``active-loc train``; the body is :mod:`active_loc.train`.
"""

from active_loc.train import main

if __name__ == "__main__":
    main()
