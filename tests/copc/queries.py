"""Answers COPC queries with laspy's CopcReader, for tests/copc.rs.

Usage: queries.py FILE.copc.laz QUERIES.json OUT.json
QUERIES.json: [{"level": L} | {"bounds": [xmin, ymin, zmin, xmax, ymax, zmax]}, ...]
OUT.json: per query, the stored integers [X, Y, Z] of every point returned, sorted; and the
COPC info (centre, half size, spacing).
"""
import json
import sys

import laspy
from laspy import CopcReader
from laspy.copc import Bounds

path, queries_path, out_path = sys.argv[1:4]
queries = json.load(open(queries_path))
answers = []
with CopcReader.open(path) as reader:
    info = reader.copc_info
    for q in queries:
        if "level" in q:
            points = reader.query(level=q["level"])
        else:
            b = q["bounds"]
            points = reader.query(bounds=Bounds(mins=b[:3], maxs=b[3:]))
        xyz = sorted(zip(points.X.tolist(), points.Y.tolist(), points.Z.tolist()))
        answers.append([list(p) for p in xyz])
    out = {
        "answers": answers,
        "centre": list(info.center),
        "halfsize": info.halfsize,
        "spacing": info.spacing,
        "point_format": reader.header.point_format.id,
        "extra": list(reader.header.point_format.extra_dimension_names),
        "returns": sorted(set(int(r) for r in reader.query().return_number)),
        "mins": list(reader.header.mins),
        "maxs": list(reader.header.maxs),
    }
json.dump(out, open(out_path, "w"))
