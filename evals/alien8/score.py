#!/usr/bin/env python
"""Run a tube tracker on every scene of this set and score it: alien4's scorer
(``../alien4/score.py``, the same options and pass rule) on these scenes.

    python score.py [--microtube PATH] [--only NAME ...] [-j 2] [--out RESULTS_DIR]
"""
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, '..', 'alien4'))
import score as alien4_score  # noqa: E402

alien4_score.HERE = HERE
alien4_score.SCENES = os.path.join(HERE, 'scenes')

if __name__ == '__main__':
    alien4_score.main()
