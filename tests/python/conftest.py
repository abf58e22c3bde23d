"""Shared pieces of the Python module's tests: the module (built in build/python, found through PYTHONPATH
as ctest sets it), the `microsim` command line (MICROSIM_BINARY) and a Heitz 2018 sampler written in numpy."""
import json
import os
import pathlib
import subprocess

import numpy as np
import pytest

import microsim  # noqa: F401  (PYTHONPATH=build/python)

ROOT = pathlib.Path(__file__).resolve().parents[2]


def binary():
    path = os.environ.get("MICROSIM_BINARY", str(ROOT / "build" / "microsim"))
    if not os.path.exists(path):
        pytest.skip(f"the microsim binary is not built ({path})")
    return path


def run_cli(*args, check=True):
    """Runs `microsim ARGS`; returns the CompletedProcess (exit code 0 or 1 accepted when check)."""
    p = subprocess.run([binary(), *map(str, args)], capture_output=True, text=True)
    if check and p.returncode not in (0, 1):
        raise AssertionError(f"microsim {' '.join(map(str, args))}: exit {p.returncode}\n{p.stderr}")
    return p


def cli_json(tmp_path, *args):
    out = tmp_path / "cli.json"
    run_cli(*args, "--json", out)
    return json.loads(out.read_text())


def heitz2018_numpy(wi, alpha, u, remap=True):
    """Heitz 2018, "Sampling the GGX Distribution of Visible Normals", JCGT 7(4), sec. 4: stretch the view
    to the hemisphere configuration, sample the projected hemisphere as a disk whose second coordinate is
    warped towards the visible half, lift to the hemisphere, unstretch. remap=False skips the warp of the
    disk (a deliberate bug: the negative control)."""
    ax, ay = alpha
    vh = np.array([ax * wi[0], ay * wi[1], wi[2]])
    vh /= np.linalg.norm(vh)
    lensq = vh[0] ** 2 + vh[1] ** 2
    t1 = np.array([-vh[1], vh[0], 0.0]) / np.sqrt(lensq) if lensq > 0 else np.array([1.0, 0.0, 0.0])
    t2 = np.cross(vh, t1)
    r, phi = np.sqrt(u[:, 0]), 2 * np.pi * u[:, 1]
    p1, p2 = r * np.cos(phi), r * np.sin(phi)
    if remap:
        s = 0.5 * (1 + vh[2])
        p2 = (1 - s) * np.sqrt(1 - p1 ** 2) + s * p2
    p3 = np.sqrt(np.maximum(0.0, 1 - p1 ** 2 - p2 ** 2))
    nh = p1[:, None] * t1 + p2[:, None] * t2 + p3[:, None] * vh
    ne = np.stack([ax * nh[:, 0], ay * nh[:, 1], np.maximum(0.0, nh[:, 2])], axis=1)
    return ne / np.linalg.norm(ne, axis=1, keepdims=True)


def view(theta_deg, phi_deg=0.0):
    t, p = np.radians(theta_deg), np.radians(phi_deg)
    return np.array([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)])
