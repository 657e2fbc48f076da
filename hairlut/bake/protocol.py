"""The baker protocol: what every table kind declares, in one place.

Each table kind is one subpackage whose ``_kind.py`` builds one :class:`Baker`,
``BAKER``, re-exported by the subpackage and named by one line of
:mod:`hairlut.bake.registry`.  The declaration module stays light (no JAX): the
callables it holds import the baking code on first call.

The protocol (every callable raises :mod:`hairlut.errors` exceptions naming the
field and value):

``resolve_recipe(given, **inputs) -> dict``
    every default made explicit; idempotent (a resolved recipe resolves to itself).
    ``inputs`` are the kind's *keyed* inputs (``Baker.keyed``, e.g. the SH tables'
    ``light``): their identity is folded into the recipe, so it is part of the cache key.
``bake(recipe, out, *, progress=None, shard=None, **options) -> dict``
    writes the asset ``out`` atomically (temporary file + ``os.replace``) and returns a
    report with at least ``out``, ``kind``, ``bytes``, ``seconds`` and ``recipe_hash``.
    ``progress(done, total)`` counts ``Baker.unit``, its first call made before any work
    with the units already done (resumed from an earlier bake's parts; 0 when none); ``shard`` ('K/N') bakes the K-th of
    N slices into a ``Baker.shard_kind`` file, or raises ValidationError when the kind
    cannot shard (:func:`no_shard`).
``load(path)``
    the validated asset as the kind's in-memory object.
``estimate(recipe) -> (bytes, seconds)``
    the planner's size and time estimate of a bake.
``merge(shards, out) -> dict`` (kinds that shard without units)
    joins ``shard_kind`` files into one asset, byte-identical to a one-shot bake.
``units`` (a :class:`Units`, kinds that shard)
    how the bake splits along one axis (sectors, tangents): the kind bakes and writes the
    units [start, stop) as one part file, and says how parts become the final asset.  The
    one shard path, :mod:`hairlut.bake.sharding`, does the rest for every such kind: resumable
    blocks in ``<out>.parts/``, ``--shard K/N``, ``--distributed`` processes (each bakes its
    share), the final asset as HDF5 virtual datasets over the parts or a copy, and
    ``merge``.  The registry runs it; such a kind's ``bake`` (None when every recipe splits)
    serves only the recipes ``Units.splits`` declines.
``describe(report) -> list[str]``
    human-readable lines about a bake report (the CLI prints them).
``bounds`` (a tuple of :class:`Bound`, one line each)
    the physical bounds of the kind's tables (α in [0, 1], re ≤ α·(k_a + k_d + k_s), ...), filed with the
    kind and its shard kind: every write of either (each part, shard, merge and asset) refuses a table beyond
    them, or not finite, naming the recipe keys (:mod:`hairlut.assets.bounds`).

Kind-specific keyword arguments of ``bake`` are :class:`Option` s, so that the CLI
offers them (``--light``, ``--block``) without naming a kind.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

from .. import errors
from ..assets.bounds import Bound
from ..assets.kinds import register_kind


@dataclass(frozen=True)
class Option:
    """A kind-specific keyword argument of ``bake`` (the CLI's ``--name``).

    ``type`` is ``str``, ``int``, ``float``, ``bool`` (a flag), ``"path"`` or a tuple of
    choices.  ``load(value, recipe, options)`` turns the command-line value into the
    input object (a path into a light, say) once the recipe is resolved.  ``sets`` makes
    the option a shortcut for ``--set KEY=VALUE``.  ``cached=False``: the option writes
    something the cache does not hold, so it needs ``--out``.  ``keyed`` (on the
    :class:`Baker`) names the options whose identity enters the recipe.
    """

    name: str
    type: object = str
    default: object = None
    help: str = ""
    load: Callable | None = None
    sets: str | None = None
    cached: bool = True
    minimum: int | None = None


def deferred(module: str, name: str) -> Callable:
    """``module``'s ``name`` (an absolute module path), imported on first call: a kind's declaration names its
    bake functions without importing them, so the registry stays light (no JAX)."""

    def call(*args, **kwargs):
        return getattr(importlib.import_module(module), name)(*args, **kwargs)

    call.__name__ = call.__qualname__ = name
    return call


@dataclass(frozen=True)
class Units:
    """How a kind's bake splits along one axis of units (see :mod:`hairlut.bake.sharding`).

    ``count(recipe, **inputs)`` units in all (a keyed input, such as a scene, may fix the count);
    ``bake_part(recipe, start, stop, total, path, **inputs)`` bakes units [start, stop) into a ``shard_kind``
    file at ``path`` (atomically) whose per-unit tables have ``axis`` as their first dimension, in the final
    storage dtype, and whose root attributes ``<axis>_start``,
    ``<axis>_stop`` and ``<axis>_total`` say which units it holds (it may instead return its last step, a
    callable that writes the part: the shard path calls it after starting the next block, so the devices
    compute one block while the host writes the one before); ``join(recipe, parts, out)`` writes
    consecutive parts as one ``shard_kind`` file; ``assemble(recipe, parts, out, **inputs)`` writes the
    self-contained asset from parts covering every unit; ``whole(recipe, parts, **inputs)`` returns
    (axes, variables, attrs): everything a virtual asset stores besides the per-unit tables (whole axes,
    tables computed from all units); ``check(recipe, path)`` (optional) raises a :mod:`hairlut.errors`
    AssetError unless a part file holds everything ``join``/``assemble``/``whole`` read from it (a part left
    by an older part format is then baked again, not resumed); ``budget(recipe, block, held, note)``
    (optional) raises BudgetError unless a process tracing ``block`` units at a time and holding the tables
    of ``held`` units at once fits the memory budget (``note`` says why it holds that many);
    ``index(recipe, path, **inputs)`` (optional) returns what ``whole`` reads from one part, as a dict of
    NumPy arrays, and then ``whole(recipe, parts, index=[...], **inputs)`` takes those instead of opening
    the parts (each process indexes its own parts as it bakes them, so the leader's assembly opens none).
    A unit's numbers must not depend on how units are grouped.

    What the protocol does for every kind that declares units, so that the kind need not: the registry bakes
    such a recipe through :func:`hairlut.bake.sharding.run` itself, the options ``block`` and ``keep_parts`` and
    the split bake's help are added to the kind's, and the report's keys are the generic ``units``,
    ``unit_range`` and ``total_units``.  ``block`` is the units per part, or a callable ``block(recipe,
    shared)`` choosing it (``shared``: the bake is a ``--shard`` or a distributed one, whose processes must cut
    the same blocks); ``block_help`` says how the default is chosen.  ``splits(recipe)`` (optional) says
    whether a recipe bakes by units at all (else the kind's own ``bake`` runs, and ``unsplit`` says why a
    split option is refused); ``start(recipe, shard=, **inputs)`` (optional) refuses inputs before any work;
    ``report(recipe, report, **inputs)`` (optional) returns the kind's own facts to add to the report.
    """

    axis: str
    count: Callable[..., int]
    bake_part: Callable
    join: Callable
    assemble: Callable
    whole: Callable
    block: int | Callable[[dict, bool], int] = 32
    check: Callable | None = None
    budget: Callable | None = None
    index: Callable | None = None
    block_help: str = ""
    splits: Callable[[dict], bool] | None = None
    unsplit: str = ""
    start: Callable | None = None
    report: Callable | None = None

    def default_block(self, recipe: dict, shared: bool) -> int:
        """Units per part when none is given."""
        return self.block(recipe, shared=shared) if callable(self.block) else self.block

    def applies(self, recipe: dict) -> bool:
        """Whether ``recipe`` bakes by units."""
        return self.splits is None or bool(self.splits(recipe))


#: The split bake's own options, added to every kind that declares units.
def _split_options(units: Units, unit: str | None) -> tuple[Option, ...]:
    default = units.block_help or f"Default: {units.block}."
    return (
        Option(
            "block",
            int,
            None,
            f"{(unit or units.axis).capitalize()} per resumable part (OUT.parts/); does not change the result.  {default}",
            minimum=1,
        ),
        Option("keep_parts", bool, False, "Keep OUT.parts/ after the final file is written."),
    )


#: The split bake's help, added to every kind that declares units.
SPLIT_HELP = """
    Split over its {unit}: finished blocks are kept in OUT.parts/, so a rerun of the same
    command after an interruption resumes and writes the same bytes as an uninterrupted bake.
    With --shard K/N it bakes the K-th of N slices into a {shard} file; `hairlut merge` joins
    them into the same bytes as a one-shot bake.  Units are spread over every local device;
    with --distributed each of JAX's processes bakes its share and process 0 writes OUT as
    HDF5 virtual datasets over OUT.parts/ (--merge copy: one file).
"""


@dataclass(frozen=True)
class Baker:
    """One table kind: its asset, recipe, bake, reader, estimate (see the module docstring)."""

    kind: str
    command: str
    description: str
    required: tuple[str, ...]
    schema: Mapping
    resolve_recipe: Callable[..., dict]
    bake: Callable[..., dict] | None
    load: Callable
    estimate: Callable[[dict], tuple[int, float]]
    describe: Callable[[dict], list] = lambda report: []
    options: tuple[Option, ...] = ()
    keyed: tuple[str, ...] = ()
    unit: str | None = "steps"  # what progress(done, total) counts; None: no progress bar on the command line
    shard_kind: str | None = None
    shard_required: tuple[str, ...] = ()
    merge: Callable | None = None
    assets: tuple[tuple[str, tuple[str, ...], str], ...] = field(default=())
    help: str = ""
    units: Units | None = None
    bounds: tuple[Bound, ...] = ()
    examples: tuple[str, ...] = ()

    def __post_init__(self):
        register_kind(self.kind, self.required, self.description, self.bounds)
        if self.units is not None and self.shard_kind is None:
            raise ValueError(f"{self.kind}: a kind with units needs a shard kind")
        if self.bake is None and (self.units is None or self.units.splits is not None):
            raise ValueError(f"{self.kind}: a kind bakes by its own bake, by units, or both")
        if self.units is not None:
            object.__setattr__(self, "options", self.options + _split_options(self.units, self.unit))
            object.__setattr__(
                self,
                "help",
                self.help.rstrip()
                + "\n"
                + SPLIT_HELP.format(unit=self.unit or self.units.axis, shard=self.shard_kind)
                + _examples(self.examples),
            )
        elif self.examples:
            object.__setattr__(self, "help", self.help.rstrip() + "\n" + _examples(self.examples))
        if self.shard_kind is not None:
            if self.merge is None and self.units is None:
                raise ValueError(f"{self.kind}: a shard kind needs a merge")
            register_kind(self.shard_kind, self.shard_required, f"a slice of a {self.kind} bake (merge joins them)", self.bounds)
        for name, required, description in self.assets:
            register_kind(name, required, description)

    @property
    def can_shard(self) -> bool:
        return self.shard_kind is not None


def _examples(lines: tuple[str, ...]) -> str:
    """The help's example block (click keeps a paragraph after \\b as written)."""
    if not lines:
        return ""
    return "\n    \b\n    Examples:\n" + "".join(f"      {line}\n" for line in lines)


def no_shard(kind: str, shard) -> None:
    """Raise the ValidationError of a kind that cannot shard when ``shard`` is given."""
    if shard is not None:
        raise errors.ValidationError("shard", shard, f"{kind} bakes cannot be sharded; bake without --shard")


def parse_shard(text) -> tuple[int, int]:
    """'K/N' (or (K, N)) → (K, N), 0 ≤ K < N (shards are numbered from 0, like JAX process indices)."""
    if isinstance(text, tuple | list) and len(text) == 2:
        text = f"{text[0]}/{text[1]}"
    k, sep, n = str(text).partition("/")
    try:
        k, n = int(k), int(n)
    except ValueError:
        k = n = -1
    if not sep or n < 1 or not 0 <= k < n:
        raise errors.ValidationError("shard", text, "use K/N with 0 ≤ K < N")
    return k, n


def prepare(baker: Baker, given: dict | None, options: Mapping | None = None) -> tuple[dict, dict]:
    """(recipe, bake keyword arguments) from a recipe and option values (CLI text or objects).

    Validates the recipe first, then loads each option that has a ``load`` against it, then
    folds the keyed inputs into the recipe (the cache key)."""
    options = dict(options or {})
    known = {o.name: o for o in baker.options}
    for name in options:
        if name not in known:
            raise errors.ValidationError(
                name, options[name], f"not an option of {baker.kind}; known: {', '.join(known) or 'none'}"
            )
    recipe = baker.resolve_recipe(given)
    inputs = {}
    for name, value in options.items():
        opt = known[name]
        if opt.sets is not None:
            continue
        if value is not None and opt.load is not None:
            value = opt.load(value, recipe, options)
        inputs[name] = value
    keyed = {k: inputs[k] for k in baker.keyed if inputs.get(k) is not None}
    if keyed:
        recipe = baker.resolve_recipe(recipe, **keyed)
    return recipe, inputs
