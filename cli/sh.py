"""``hairlut sh``: spherical-harmonic utilities (environment-light projection)."""

from __future__ import annotations

import json

import click

from .format import num

#: ``hairlut.envlight.LAYOUTS``, spelled here so that ``hairlut --help`` need not import JAX (tests/test_sh_cli.py
#: checks that the two agree).
LAYOUTS = ("auto", "latlong", "cube")


@click.group("sh")
def sh_group():
    """Spherical-harmonic utilities."""


@sh_group.command("project")
@click.argument("envmap", type=click.Path(dir_okay=False))
@click.option(
    "--bands",
    type=click.IntRange(min=1, max=65),
    default=8,
    show_default=True,
    help="Number of SH bands (lmax + 1); 8 bands = 64 coefficients, the paper's specular light.",
)
@click.option(
    "--layout",
    type=click.Choice(LAYOUTS),
    default="auto",
    show_default=True,
    help="Map layout; auto reads the EXR 'envmap' attribute and the aspect ratio.",
)
@click.option("--up", type=click.Choice(["z", "y"]), default="z", show_default=True, help="Which world axis the map's up is.")
@click.option("--out", type=click.Path(dir_okay=False), help="Write the coefficients as an sh_light HDF5 table.")
@click.option("--json", "as_json", is_flag=True, help="Print coefficients and errors as JSON.")
def project_cmd(envmap, bands, layout, up, out, as_json):
    """Project an EXR environment map onto real SH: a_i = ∫ L(ω) Y_i(ω) dω.

    Texels are weighted by their exact solid angle.  Reports the band-limiting
    error: the relative L2 energy of the map that the bands leave out.

    \b
    Examples (ENV.exr: your own map; lat-long, or a cube cross with --layout cube):
      hairlut sh project ENV.exr --bands 3
      hairlut sh project ENV.exr --layout cube --bands 8 --out light.h5
    """
    from hairlut.envlight import load_env_light, write_light

    light = load_env_light(envmap, bands - 1, layout, up)
    if out:
        write_light(out, light, {"source_sha256": light.source_sha256, "layout": light.layout, "up": up, "lmax": bands - 1})
    doc = {
        "source": envmap,
        "layout": light.layout,
        "bands": bands,
        "channels": list(light.channels),
        "band_error": dict(zip(light.channels, light.band_error.tolist())),
        "coeffs": light.coeffs.tolist(),
        "out": out,
    }
    if as_json:
        click.echo(json.dumps(doc, indent=2))
        return
    click.echo(f"{envmap}: {light.layout} map, {bands} bands ({bands * bands} coefficients), channels {','.join(light.channels)}")
    for c, name in enumerate(light.channels):
        click.echo(f"  {name}: a_00 = {num(light.coeffs[0, c])}  band-limiting error (relative L2) {light.band_error[c]:.3e}")
    if out:
        click.echo(f"wrote {out}")
