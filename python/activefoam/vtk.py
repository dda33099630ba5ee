"""VTK XML PolyData (.vtp) and collection (.pvd) text for snapshots: the same files as the
C++ writer (vtk/src/vtk.cc) that `foam export` uses, so ParaView sees one format."""

from __future__ import annotations

from typing import Any, Iterable, List, Sequence, Tuple
from xml.sax.saxutils import quoteattr


def _num(v: float) -> str:
    return repr(float(v))


def _rows(values: Sequence[Any], per_line: int) -> str:
    lines = []
    for i in range(0, len(values), per_line):
        lines.append("          " + " ".join(str(v) for v in values[i:i + per_line]))
    return "\n".join(lines) + ("\n" if lines else "")


def polydata(snap: Any) -> str:
    """A SnapshotData message as a .vtp document: points, triangles, per-point cell id, and per
    triangle cell id, spheroid label and cell pressure."""
    x: List[float] = list(snap.x)
    tri: List[int] = list(snap.tri)
    if len(x) % 3 or len(tri) % 3:
        raise ValueError("snapshot: coordinates or triangles are not whole")
    n_points, n_tris = len(x) // 3, len(tri) // 3
    vertex_cell = list(snap.vertex_cell) or [0] * n_points
    labels, pressure = list(snap.cell_label), list(snap.cell_pressure)
    tri_cell = [vertex_cell[tri[3 * t]] for t in range(n_tris)]

    def per_cell(values: List[Any], c: int, fallback: Any) -> Any:
        return values[c] if 0 <= c < len(values) else fallback

    out = [
        '<?xml version="1.0"?>\n',
        '<VTKFile type="PolyData" version="1.0" byte_order="LittleEndian" '
        'header_type="UInt64">\n',
        "  <PolyData>\n",
        "    <FieldData>\n",
        f'      <DataArray type="Float64" Name="TIME" NumberOfTuples="1" format="ascii">'
        f"{_num(snap.t_s)}</DataArray>\n",
        f'      <DataArray type="Int64" Name="STEP" NumberOfTuples="1" format="ascii">'
        f"{snap.step}</DataArray>\n",
        "    </FieldData>\n",
        f'    <Piece NumberOfPoints="{n_points}" NumberOfVerts="0" NumberOfLines="0" '
        f'NumberOfStrips="0" NumberOfPolys="{n_tris}">\n',
        '      <PointData Scalars="cell_id">\n',
        '        <DataArray type="Int32" Name="cell_id" format="ascii">\n',
        _rows(vertex_cell, 16),
        "        </DataArray>\n",
        "      </PointData>\n",
        '      <CellData Scalars="cell_id">\n',
        '        <DataArray type="Int32" Name="cell_id" format="ascii">\n',
        _rows(tri_cell, 16),
        "        </DataArray>\n",
        '        <DataArray type="Int32" Name="spheroid" format="ascii">\n',
        _rows([per_cell(labels, c, 0) for c in tri_cell], 16),
        "        </DataArray>\n",
        '        <DataArray type="Float64" Name="pressure" format="ascii">\n',
        _rows([_num(per_cell(pressure, c, 0.0)) for c in tri_cell], 8),
        "        </DataArray>\n",
        "      </CellData>\n",
        "      <Points>\n",
        '        <DataArray type="Float64" Name="Points" NumberOfComponents="3" '
        'format="ascii">\n',
        "".join(f"          {_num(x[3 * i])} {_num(x[3 * i + 1])} {_num(x[3 * i + 2])}\n"
                for i in range(n_points)),
        "        </DataArray>\n",
        "      </Points>\n",
        "      <Polys>\n",
        '        <DataArray type="Int64" Name="connectivity" format="ascii">\n',
        "".join(f"          {tri[3 * t]} {tri[3 * t + 1]} {tri[3 * t + 2]}\n"
                for t in range(n_tris)),
        "        </DataArray>\n",
        '        <DataArray type="Int64" Name="offsets" format="ascii">\n',
        _rows([3 * (t + 1) for t in range(n_tris)], 16),
        "        </DataArray>\n",
        "      </Polys>\n",
        "    </Piece>\n",
        "  </PolyData>\n",
        "</VTKFile>\n",
    ]
    return "".join(out)


def collection(time_and_file: Iterable[Tuple[float, str]]) -> str:
    """series.pvd: the snapshots as a time series."""
    lines = ['<?xml version="1.0"?>\n',
             '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">\n',
             "  <Collection>\n"]
    for t, name in time_and_file:
        lines.append(f'    <DataSet timestep="{_num(t)}" group="" part="0" file={quoteattr(name)}/>\n')
    lines.append("  </Collection>\n</VTKFile>\n")
    return "".join(lines)
