#!/usr/bin/env python3
"""Validates real outputs of the scan2model command against the JSON Schemas of docs/schemas/ (docs/cli.md).

    tests/json_schemas_test.py SCAN2MODEL SOURCE_DIR

Runs the command on small shipped or generated data to produce every kind of document (info of a point cloud, an
E57 file and a recording; fit of each primitive, with a reference and robust; B-spline curve and surface; Hermite curves; surface of
revolution, helical and spiral surfaces; a constrained part; detect; a batch's records and summary; a views manifest
written by export; an error; devices) and validates each against its schema (Draft 2020-12, python3-jsonschema).
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
        ("bspline.schema.json", ["fit", "--json", "--model", "bspline-curve", "--closed", "--control-points", "12",
                                 os.path.join(work, "ellipse.xyz")] + quick, None),
        ("bspline.schema.json", ["fit", "--json", "--model", "bspline-surface", "--control-points", "5x5",
                                 os.path.join(work, "sheet.xyz")] + quick, None),
        ("hermite.schema.json", ["fit", "--json", "--model", "hermite-curve", "--closed", "--elements", "6",
                                 os.path.join(work, "ellipse.xyz")] + quick, None),
        ("hermite.schema.json", ["fit", "--json", "--model", "hermite-curve", "--closed", "--elements", "6",
                                 "--fairness-fraction", "0.5", os.path.join(work, "ellipse.xyz")] + quick, None),
        ("hermite.schema.json", ["fit", "--json", "--model", "hermite-curve", "--degree", "3", "--c2",
                                 "--interpolate", "--alpha3", "1", os.path.join(work, "ellipse.xyz")], None),
        ("multiview.schema.json", ["fit", "--json", "--model", "revolution", "--control-points", "8", vase] + quick, None),
        ("multiview.schema.json", ["fit", "--json", "--model", "helical", "--control-points", "6", vase] + quick, None),
        ("multiview.schema.json", ["fit", "--json", "--model", "spiral", "--control-points", "6", vase] + quick, None),
        ("part_fit.schema.json", ["fit", "--json", "--model", "part:" + part, block] + quick, None),
        ("detect.schema.json", ["detect", "--json", "--model", "plane", "--model", "sphere",
                                os.path.join(work, "scene.xyz")], None),
        ("error.schema.json", ["fit", "--json", "--model", "sphere", os.path.join(work, "nowhere.ply")], None),
        ("devices.schema.json", ["devices", "--json"], None),
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
