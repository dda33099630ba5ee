"""Reads a snapshot written by foam export / foam-run (.vtp, ASCII): its time, every vertex's
position and cell, and the triangles (the snapshot_*.py beside it)."""
import re

import numpy as np


def read(path):
    """(t in s, cell_id per vertex, positions (n, 3), triangles (m, 3) of vertex indices)."""
    txt = open(path).read()
    t = float(re.search(r'Name="TIME"[^>]*>([^<]*)<', txt).group(1))

    def arr(name, dtype=float):
        m = re.search(r'Name="%s"[^>]*>(.*?)</DataArray>' % name, txt, re.S)
        return np.array(m.group(1).split(), dtype=dtype)

    X = np.array(re.search(r'<Points>.*?<DataArray[^>]*>(.*?)</DataArray>', txt, re.S).group(1)
                 .split(), float).reshape(-1, 3)
    return t, arr("cell_id", int), X, arr("connectivity", int).reshape(-1, 3)
