import os
import sys

# Lets tests import their helpers (reference.py, scenes.py) however pytest is invoked.
sys.path.insert(0, os.path.dirname(__file__))
