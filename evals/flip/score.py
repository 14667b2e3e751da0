#!/usr/bin/env python
"""Score the mirrored and rotated scenes (``make.py``) as alien4's score.py does."""
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, '..', 'alien4'))
import score as alien4_score  # noqa: E402

alien4_score.SCENES = os.path.join(HERE, 'scenes')

if __name__ == '__main__':
    sys.exit(alien4_score.main())
