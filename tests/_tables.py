"""Small real tables shared by the asset-store tests."""

import numpy as np

from hairlut.assets import Axis, Variable, register_kind, write_table

# a test-only kind (hairlut itself bakes no kk_lobes tables): declared here, as a kind's module would
register_kind("kk_lobes", ("diffuse", "specular"), "Kajiya-Kay diffuse and specular kernels sampled on (theta, theta') grids")

RECIPE = {"n_theta": 33, "n_theta_v": 17, "exponents": [8.0, 49.0], "storage": "float32", "nested": {"a": [1, 2], "b": None}}


def lobes_table(path, recipe=RECIPE, rng=None, size=(2, 33, 17)):
    """Write a kk_lobes table with random contents of the given size; return (path, arrays)."""
    rng = rng or np.random.default_rng(0)
    p, nt, nv = size
    theta = np.linspace(0, np.pi, nt)
    theta_v = np.linspace(0, np.pi, nv)
    diffuse = np.sin(theta).astype(np.float32)
    specular = rng.random((p, nt, nv)).astype(np.float32)
    axes = [
        Axis("theta", theta, "rad", "angle(light, tangent)"),
        Axis("theta_v", theta_v, "rad", "angle(tangent, view)", period=None),
        Axis("exponent", np.arange(1.0, p + 1), "1", "specular exponent"),
    ]
    variables = [
        Variable("diffuse", diffuse, ("theta",), "1", "sin theta"),
        Variable("specular", specular, ("exponent", "theta", "theta_v"), "1", "KK specular", chunks=(1, nt, nv)),
    ]
    write_table(path, "kk_lobes", recipe, axes, variables, attrs={"note": "test"})
    return path, {"diffuse": diffuse, "specular": specular, "theta": theta, "theta_v": theta_v}


def virtual_over(path, source, dset="specular", shape=(2, 33, 17), axis="exponent"):
    """Give table ``path`` a dataset 'ext', virtual over dataset ``dset`` of file ``source`` (its rows [0, n) along
    ``axis``, the label of its first dimension); returns ``path``."""
    import h5py

    with h5py.File(path, "r+") as f:
        lay = h5py.VirtualLayout(shape=shape, dtype="f4")
        lay[...] = h5py.VirtualSource(str(source), dset, shape=shape)
        f.create_virtual_dataset("ext", lay, fillvalue=0).dims[0].label = axis
    return path


def declare_rows(part, start: int, stop: int, axis="exponent"):
    """Write the range a part of a split bake declares it holds (``<axis>_start``, ``<axis>_stop``); returns it."""
    import h5py

    with h5py.File(part, "r+") as f:
        f.attrs[f"{axis}_start"], f.attrs[f"{axis}_stop"] = np.int64(start), np.int64(stop)
    return part
