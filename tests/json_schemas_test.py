#!/usr/bin/env python3
"""Validates real outputs of the scan2model command against the JSON Schemas of docs/schemas/ (docs/cli.md).

    tests/json_schemas_test.py SCAN2MODEL SOURCE_DIR

Runs the command on small shipped or generated data to produce every kind of document (info of a point cloud, an E57
file and a recording; fit of each primitive, with a reference and robust, with --criterion and --uncertainty;
B-spline curve and surface; Hermite curves; surface of revolution, helical and spiral surfaces; a constrained part;
detect; a batch's records and summary; a views manifest written by export; an inspection against a nominal mesh; an
error; devices) and validates each against its schema (Draft 2020-12, python3-jsonschema).
Every schema is first checked against the metaschema. Exits 77 (ctest: skipped) when python3-jsonschema is missing.
"""
import json
import math
import os
import random
import struct
import subprocess
import sys
import tempfile

try:
    import jsonschema
except ImportError:
    print("SKIP: python3-jsonschema is not installed (apt-get install python3-jsonschema)")
    sys.exit(77)


def load_schemas(folder):
    schemas = {}
    for name in sorted(os.listdir(folder)):
        if name.endswith(".schema.json"):
            with open(os.path.join(folder, name)) as f:
                schemas[name] = json.load(f)
    return schemas


def validator_for(schemas, name):
    """A validator resolving the schemas' references to each other by file name (their $id)."""
    schema = schemas[name]
    try:  # jsonschema >= 4.18
        from referencing import Registry, Resource
        from referencing.jsonschema import DRAFT202012
        registry = Registry().with_resources(
            [(n, Resource.from_contents(s, default_specification=DRAFT202012)) for n, s in schemas.items()])
        return jsonschema.Draft202012Validator(schema, registry=registry)
    except ImportError:  # Debian 12's python3-jsonschema (4.10)
        resolver = jsonschema.RefResolver(base_uri=name, referrer=schema, store=dict(schemas))
        return jsonschema.Draft202012Validator(schema, resolver=resolver)


def write_points(path, points):
    with open(path, "w") as f:
        for p in points:
            f.write(" ".join(repr(c) for c in p) + "\n")


def subsample_views(manifest, out_dir, step):
    """A lighter copy of a views manifest written by scan2model (binary PLY views of doubles): every step-th point
    of each view as XYZ text, the same poses and units: the documents' members do not depend on the number of points,
    the fits' time does (this whole test runs in about 18 s of CPU time; the helical and spiral starts dominate)."""
    os.makedirs(out_dir, exist_ok=True)
    with open(manifest) as f:
        m = json.load(f)
    for k, view in enumerate(m["views"]):
        with open(os.path.join(os.path.dirname(manifest), view["file"]), "rb") as f:
            data = f.read()
        end = data.index(b"end_header\n") + len(b"end_header\n")
        header = data[:end].decode().split("\n")
        count = next(int(l.split()[2]) for l in header if l.startswith("element vertex"))
        props = sum(1 for l in header if l.startswith("property"))
        values = struct.unpack_from("<%dd" % (count * props), data, end)
        points = [values[i * props:i * props + 3] for i in range(0, count, step)]
        view["file"] = "view_%03d.xyz" % k
        write_points(os.path.join(out_dir, view["file"]), points)
    path = os.path.join(out_dir, "views.json")
    with open(path, "w") as f:
        json.dump(m, f)
    return path


def make_inputs(work):
    rng = random.Random(5)
    # A curve: a closed ellipse in the xy plane with noise.
    write_points(os.path.join(work, "ellipse.xyz"),
                 [(3 * math.cos(t) + rng.gauss(0, 0.01), 2 * math.sin(t) + rng.gauss(0, 0.01), 0.0)
                  for t in [2 * math.pi * k / 300 for k in range(300)]])
    # A surface: a gently curved sheet.
    write_points(os.path.join(work, "sheet.xyz"),
                 [(x, y, 0.1 * x * x - 0.05 * y * y + rng.gauss(0, 0.002))
                  for x in [i / 10 for i in range(-10, 11)] for y in [j / 10 for j in range(-10, 11)]])
    # A scene for detect: a plane and a sphere.
    scene = [(rng.uniform(-2, 2), rng.uniform(-2, 2), rng.gauss(0, 0.002)) for _ in range(3000)]
    for _ in range(1500):
        d = [rng.gauss(0, 1) for _ in range(3)]
        n = math.sqrt(sum(c * c for c in d))
        scene.append(tuple(c + 0.5 * x / n + rng.gauss(0, 0.002) for c, x in zip((0.0, 0.0, 1.0), d)))
    write_points(os.path.join(work, "scene.xyz"), scene)
    with open(os.path.join(work, "objects.csv"), "w") as f:
        f.write("id,input,model\nsphere,scene.xyz,sphere\nmissing,nowhere.ply,sphere\n")
    # The ISO 10360-6 features besides the four primitives: a circle, a line and a torus with noise.
    write_points(os.path.join(work, "circle.xyz"),
                 [(5 * math.cos(t) + rng.gauss(0, 0.01), 5 * math.sin(t) + rng.gauss(0, 0.01), 1 + rng.gauss(0, 0.01))
                  for t in [2 * math.pi * k / 200 for k in range(200)]])
    write_points(os.path.join(work, "line.xyz"),
                 [(t + rng.gauss(0, 0.01), 2 * t + rng.gauss(0, 0.01), -t + rng.gauss(0, 0.01))
                  for t in [k / 50 for k in range(100)]])
    torus = []
    for _ in range(1500):
        u, v = rng.uniform(0, 2 * math.pi), rng.uniform(0, 2 * math.pi)
        r = 10 + 3 * math.cos(v) + rng.gauss(0, 0.01)
        torus.append((r * math.cos(u), r * math.sin(u), 3 * math.sin(v)))
    write_points(os.path.join(work, "torus.xyz"), torus)
    make_inspection_inputs(work)


def make_inspection_inputs(work):
    """A nominal (ASCII STL, one solid per face group): a box [-30, 30] x [-20, 20] x [0, 20] and beside it a pin
    (a 24-sided prism of radius 5 standing from z = 0 to 15 at x = 45), a scan of both moved by a small rigid
    motion, and a checks file with every check type."""
    rng = random.Random(11)
    solids = {}
    corners = [((i & 1) and 30 or -30, (i & 2) and 20 or -20, (i & 4) and 20 or 0) for i in range(8)]
    quads = {"px": (1, 3, 7, 5), "mx": (0, 4, 6, 2), "py": (2, 6, 7, 3), "my": (0, 1, 5, 4),
             "top": (4, 5, 7, 6), "bottom": (0, 2, 3, 1)}
    for name, (a, b, c, d) in quads.items():
        solids[name] = [(corners[a], corners[b], corners[c]), (corners[a], corners[c], corners[d])]
    sides, radius, height, cx = 24, 5.0, 15.0, 45.0
    ring = [(cx + radius * math.cos(2 * math.pi * k / sides), radius * math.sin(2 * math.pi * k / sides))
            for k in range(sides)]
    solids["pin"], solids["pin_ends"] = [], []
    for k in range(sides):
        (x0, y0), (x1, y1) = ring[k], ring[(k + 1) % sides]
        solids["pin"] += [((x0, y0, 0.0), (x1, y1, 0.0), (x1, y1, height)),
                          ((x0, y0, 0.0), (x1, y1, height), (x0, y0, height))]
        solids["pin_ends"] += [((cx, 0.0, height), (x0, y0, height), (x1, y1, height)),
                               ((cx, 0.0, 0.0), (x1, y1, 0.0), (x0, y0, 0.0))]
    with open(os.path.join(work, "nominal.stl"), "w") as f:
        for name, triangles in solids.items():
            f.write("solid %s\n" % name)
            for t in triangles:
                f.write("facet normal 0 0 0\nouter loop\n" + "".join("vertex %r %r %r\n" % v for v in t) +
                        "endloop\nendfacet\n")
            f.write("endsolid %s\n" % name)
    # Points on the faces the scanner sees (not the bottoms), noise 0.002 along the normal.
    points = []
    for _ in range(500):
        p, q, e = rng.random(), rng.random(), rng.gauss(0, 0.002)
        points += [(30 + e, -20 + 40 * p, 20 * q), (-30 - e, -20 + 40 * p, 20 * q), (-30 + 60 * p, 20 + e, 20 * q),
                   (-30 + 60 * p, -20 - e, 20 * q), (-30 + 60 * p, -20 + 40 * q, 20 + e)]
        a, z = 2 * math.pi * rng.random(), height * rng.random()
        # On the prism's facet, not on the circle through its vertices.
        k = int(a / (2 * math.pi / sides)) % sides
        (x0, y0), (x1, y1) = ring[k], ring[(k + 1) % sides]
        nx, ny = (y1 - y0), -(x1 - x0)
        n = math.hypot(nx, ny)
        points.append((x0 + p * (x1 - x0) + e * nx / n, y0 + p * (y1 - y0) + e * ny / n, z))
    angle, shift = 0.01, (0.3, -0.2, 0.1)
    c, s = math.cos(angle), math.sin(angle)
    with open(os.path.join(work, "part_scan.xyz"), "w") as f:
        for x, y, z in points:
            f.write("%r %r %r\n" % (c * x - s * y + shift[0], s * x + c * y + shift[1], z + shift[2]))
    checks = {"schema": "scan2model.checks/1", "part": "block with a pin", "datums": ["top", "my", "mx"],
              "checks": [{"name": "top profile", "type": "profile", "group": "top", "tolerance": 0.1},
                         {"name": "top flatness", "type": "flatness", "group": "top", "tolerance": 0.05},
                         {"name": "pin position", "type": "position", "group": "pin", "tolerance": 0.1},
                         {"name": "pin to px", "type": "distance", "group": "px", "to": "pin", "lower": -0.1,
                          "upper": 0.1},
                         {"name": "pin diameter", "type": "diameter", "group": "pin", "lower": -0.05,
                          "upper": 0.05}]}
    with open(os.path.join(work, "part.checks.json"), "w") as f:
        json.dump(checks, f, indent=1)


def main():
    cli, source = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
    schemas = load_schemas(os.path.join(source, "docs", "schemas"))
    failures, passed = [], 0
    for name, schema in schemas.items():
        try:
            jsonschema.Draft202012Validator.check_schema(schema)
            passed += 1
        except jsonschema.SchemaError as e:
            failures.append(f"{name}: not a valid schema: {e.message}")

    nist = os.path.join(source, "tests", "data", "nist")
    work = tempfile.mkdtemp(prefix="s2m_schemas_")
    make_inputs(work)
    vase = subsample_views(os.path.join(source, "recordings", "demo_vase", "views.json"),
                           os.path.join(work, "vase"), 20)
    block = subsample_views(os.path.join(source, "recordings", "demo_block", "views.json"),
                            os.path.join(work, "block"), 40)
    part = os.path.join(source, "docs", "examples", "counterbored_block.part.json")
    quick = ["--max-iterations", "3"]
    # (schema file, command arguments, where the document is: stdout or a file)
    runs = [
        ("info.schema.json", ["info", "--json", os.path.join(nist, "sph1.ds")], None),
        ("info.schema.json", ["info", "--json", os.path.join(source, "tests", "data", "e57", "spherical_grid.e57")], None),
        ("info.schema.json", ["info", "--json", os.path.join(source, "recordings", "pot.s2mrec")], None),
        ("fit.schema.json", ["fit", "--json", "--model", "plane", os.path.join(nist, "pla1.ds")], None),
        ("fit.schema.json", ["fit", "--json", "--model", "sphere", os.path.join(nist, "sph1.ds"),
                             "--reference", os.path.join(nist, "sph1.fit")], None),
        ("fit.schema.json", ["fit", "--json", "--model", "cylinder", os.path.join(nist, "cyl1.ds")], None),
        ("fit.schema.json", ["fit", "--json", "--model", "cone", os.path.join(nist, "con1.ds"), "--loss", "huber"], None),
        ("fit.schema.json", ["fit", "--json", "--model", "sphere", "--robust", os.path.join(work, "scene.xyz")], None),
        ("fit.schema.json", ["fit", "--json", "--model", "cylinder", os.path.join(nist, "cyl1.ds"), "--criterion",
                             "circumscribed", "--uncertainty", "linear"], None),
        ("fit.schema.json", ["fit", "--json", "--model", "sphere", os.path.join(nist, "sph1.ds"), "--criterion",
                             "minzone", "--uncertainty", "monte-carlo:20"], None),
        ("fit.schema.json", ["fit", "--json", "--model", "circle", os.path.join(work, "circle.xyz"), "--criterion",
                             "inscribed", "--uncertainty", "linear"], None),
        ("fit.schema.json", ["fit", "--json", "--model", "line", os.path.join(work, "line.xyz"), "--criterion",
                             "minzone", "--uncertainty", "monte-carlo:20"], None),
        ("fit.schema.json", ["fit", "--json", "--model", "torus", os.path.join(work, "torus.xyz"), "--uncertainty",
                             "linear"], None),
        ("bspline.schema.json", ["fit", "--json", "--model", "bspline-curve", "--closed", "--control-points", "12",
                                 os.path.join(work, "ellipse.xyz")] + quick, None),
        ("bspline.schema.json", ["fit", "--json", "--model", "bspline-surface", "--control-points", "5x5",
                                 os.path.join(work, "sheet.xyz")] + quick, None),
        ("hermite.schema.json", ["fit", "--json", "--model", "hermite-curve", "--closed", "--elements", "6",
                                 os.path.join(work, "ellipse.xyz")] + quick, None),
        ("hermite.schema.json", ["fit", "--json", "--model", "hermite-curve", "--closed", "--elements", "6",
                                 "--fairness-fraction", "0.5", os.path.join(work, "ellipse.xyz")] + quick, None),
        ("hermite.schema.json", ["fit", "--json", "--model", "hermite-curve", "--closed", "--elements", "6",
                                 "--geometric-variation", "0.5", os.path.join(work, "ellipse.xyz")] + quick, None),
        ("hermite.schema.json", ["fit", "--json", "--model", "hermite-curve", "--degree", "3", "--c2",
                                 "--interpolate", "--alpha3", "1", os.path.join(work, "ellipse.xyz")], None),
        ("multiview.schema.json", ["fit", "--json", "--model", "revolution", "--control-points", "8", vase,
                                   "--uncertainty", "monte-carlo:20", "--efd", "6"] + quick, None),
        ("multiview.schema.json", ["fit", "--json", "--model", "revolution", "--wall", "--fill-height", "60",
                                   os.path.join(source, "recordings", "demo_wall", "views.json")], None),
        ("multiview.schema.json", ["fit", "--json", "--model", "helical", "--control-points", "6", vase,
                                   "--uncertainty", "linear"] + quick, None),
        ("multiview.schema.json", ["fit", "--json", "--model", "spiral", "--control-points", "6", vase,
                                   "--uncertainty", "monte-carlo:20"] + quick, None),
        ("part_fit.schema.json", ["fit", "--json", "--model", "part:" + part, block] + quick, None),
        ("detect.schema.json", ["detect", "--json", "--model", "plane", "--model", "sphere",
                                os.path.join(work, "scene.xyz")], None),
        ("error.schema.json", ["fit", "--json", "--model", "sphere", os.path.join(work, "nowhere.ply")], None),
        ("devices.schema.json", ["devices", "--json"], None),
        ("inspection.schema.json", ["inspect", "--nominal", os.path.join(work, "nominal.stl"),
                                    os.path.join(work, "part_scan.xyz"), "--part", os.path.join(work, "part.checks.json"),
                                    "--operator", "J. Doe", "-o", os.path.join(work, "inspection")],
         os.path.join(work, "inspection.json")),
        ("inspection.schema.json", ["inspect", "--json", "--nominal", os.path.join(work, "nominal.stl"),
                                    os.path.join(work, "part_scan.xyz"), "--part", os.path.join(work, "part.checks.json"),
                                    "--uncertainty", "monte-carlo:20"], None),
        ("inspection.schema.json", ["inspect", "--json", "--nominal", os.path.join(work, "nominal.stl"),
                                    os.path.join(work, "part_scan.xyz"), "--uncertainty", "none"], None),
        ("views.schema.json", ["export", "-q", os.path.join(source, "tests", "data", "e57", "cartesian_mixed.e57"),
                               "-o", os.path.join(work, "views")], os.path.join(work, "views", "views.json")),
        ("batch_summary.schema.json", ["batch", "-q", os.path.join(work, "objects.csv"), "-o",
                                       os.path.join(work, "batch")], os.path.join(work, "batch", "summary.json")),
        ("batch_object.schema.json", None, os.path.join(work, "batch", "objects", "sphere.json")),
        ("batch_object.schema.json", None, os.path.join(work, "batch", "objects", "missing.json")),
    ]
    for schema_name, args, document_file in runs:
        what = " ".join(args) if args else document_file
        if args is not None:
            r = subprocess.run([cli] + args, cwd=work, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            text = r.stdout
        if document_file is not None:
            try:
                with open(document_file) as f:
                    text = f.read()
            except OSError as e:
                failures.append(f"{what}: no document ({e})")
                continue
        try:
            document = json.loads(text)
        except json.JSONDecodeError as e:
            failures.append(f"{what}: output is not JSON ({e}); stderr: {r.stderr[-500:] if args else ''}")
            continue
        errors = sorted(validator_for(schemas, schema_name).iter_errors(document), key=lambda e: list(e.path))
        if errors:
            for e in errors[:10]:
                failures.append(f"{what}: {schema_name}: at /{'/'.join(str(p) for p in e.path)}: {e.message[:300]}")
        else:
            passed += 1
            print(f"ok   {schema_name:28s} {what[:110]}")
    for f in failures:
        print("FAIL " + f)
    print(f"{passed} passed, {len(failures)} failed")
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
