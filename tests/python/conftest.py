"""Shared data of the Python binding tests: the repository's shipped files and small synthetic point sets."""

import os
import pathlib

import numpy as np
import pytest

SOURCE = pathlib.Path(os.environ.get("S2M_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))


@pytest.fixture(scope="session")
def source_dir() -> pathlib.Path:
    return SOURCE


@pytest.fixture(scope="session")
def nist_dir() -> pathlib.Path:
    return SOURCE / "tests" / "data" / "nist"


@pytest.fixture(scope="session")
def vase_views() -> pathlib.Path:
    return SOURCE / "recordings" / "demo_vase" / "views.json"


def sphere_points(n=400, centre=(1.0, -2.0, 0.5), radius=3.0, noise=0.0, seed=1):
    """n points on a sphere (a Fibonacci spiral), with Gaussian noise along the normal."""
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    phi = i * 2.399963229728653
    rho = np.sqrt(1 - z * z)
    normals = np.stack([rho * np.cos(phi), rho * np.sin(phi), z], axis=1)
    r = radius + noise * np.random.default_rng(seed).normal(size=(n, 1))
    return np.ascontiguousarray(np.asarray(centre) + r * normals)


def ellipse_points(n=120, a=4.0, b=2.0, noise=0.0, seed=2):
    """A closed planar curve (an ellipse in z = 0) sampled n times, with noise in x and y."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    p = np.stack([a * np.cos(t), b * np.sin(t), np.zeros(n)], axis=1)
    p[:, :2] += noise * np.random.default_rng(seed).normal(size=(n, 2))
    return p


def lighter_views(views, step):
    """Every step-th point of each view, the same poses and units: the documents' members do not depend on the
    number of points, the fits' time does."""
    import scan2model

    return scan2model.ScanSet(
        [scan2model.Scan(np.ascontiguousarray(v.points[::step]), units=v.units, world_T_scan=v.world_T_scan) for v in views], views.name)


@pytest.fixture(scope="session")
def schema_validator():
    """validate(document, 'fit.schema.json'): the JSON Schemas of docs/schemas/ with their references to each
    other resolved (python3-jsonschema; the tests using it are skipped without it)."""
    jsonschema = pytest.importorskip("jsonschema")
    import json

    folder = SOURCE / "docs" / "schemas"
    schemas = {p.name: json.loads(p.read_text()) for p in folder.glob("*.schema.json")}

    def validate(document, name):
        schema = schemas[name]
        try:  # jsonschema >= 4.18
            from referencing import Registry, Resource
            from referencing.jsonschema import DRAFT202012

            registry = Registry().with_resources(
                [(n, Resource.from_contents(s, default_specification=DRAFT202012)) for n, s in schemas.items()])
            validator = jsonschema.Draft202012Validator(schema, registry=registry)
        except ImportError:  # Debian 12's python3-jsonschema (4.10)
            resolver = jsonschema.RefResolver(base_uri=name, referrer=schema, store=dict(schemas))
            validator = jsonschema.Draft202012Validator(schema, resolver=resolver)
        validator.validate(document)

    return validate
