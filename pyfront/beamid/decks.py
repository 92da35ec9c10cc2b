"""Namelist decks (format: docs/decks.md), read and written with f90nml.

Tasks: ``static`` (arc-length), ``fe_static`` and ``fe_modes`` (finite
elements, group ``&fe``), ``simulate`` (dynamics, group ``&simulate``: the
arguments of :func:`beamid.simulate`; writes ``<output>_history.csv``) and the
estimation tasks (:mod:`beamid.fit_decks`).

The same files drive the batch executable ``beamid-batch``; this module
applies the same checks so that a deck fails the same way in both.
"""
from __future__ import annotations

import math
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import f90nml
import numpy as np

from .errors import InputError
from .loads import Load, RadialWire, TipLoad
from .model import Model, _core
from .static import OUTPUTS, StaticResult, solve_static

GROUPS = {
    "beamid": {"task", "output", "preset", "nbeams"},
    "model": {"l", "ei", "ea", "rho", "c", "m", "j", "mu", "c_drag", "joint_flex",
              "axial_coupling", "root_flex", "eta", "r_motor", "tau_motor",
              "m_elbow", "j_elbow", "mu_elbow", "c_elbow", "elbow_flex",
              "m_tip", "j_tip", "mu_tip", "c_tip"},
    "load": {"kind", "fx", "fy", "moment", "wire_length"},
    "static": {"wrt", "shape_points", "tol"},
    "fe": {"elements_per_beam", "moment_form", "rotary_inertia", "point_masses", "steps",
           "tol"},
    "published": {"table", "row", "quantity", "value", "digits", "deviation", "note"},
    "simulate": {"t_out", "t_end", "n_out", "elements_per_beam", "integrator", "dt", "rtol",
                 "atol", "motor_gain", "friction", "friction_velocity"},
}
TASKS = ("static", "fe_static", "fe_modes", "simulate")
#: tasks of estimation decks (&experiment, &fit groups), read by beamid.fit_decks
ESTIMATION_TASKS = ("fit", "compare", "diagnose", "improve")
#: defaults of the &fe group (docs/fe.md)
FE_DEFAULTS = {"elements_per_beam": 4, "moment_form": "eq78", "rotary_inertia": False,
               "point_masses": True, "steps": 0, "tol": 0.0}
#: &simulate options of a dynamic deck, defaults resolved as beamid.simulate does
#: (friction None: "sign" for both integrators, as beamid.simulate; 0 or None: the default)
SIMULATE_DEFAULTS = {"elements_per_beam": 4, "integrator": "implicit", "friction": None,
                     "dt": None, "rtol": None, "atol": None, "motor_gain": 0.0,
                     "friction_velocity": None}
#: default number of output times with t_end
DEFAULT_N_OUT = 101
_PER_BEAM = {"l": "L{}", "ei": "EI{}", "ea": "EA{}", "rho": "rho{}", "c": "C{}"}
_PER_POINT = {"m": "m_{}", "j": "J_{}", "mu": "mu_{}", "c_drag": "c_{}"}
_GLOBAL = ("axial_coupling", "root_flex", "eta", "r_motor", "tau_motor")
#: named scalars of &model for the elbow (joint 1) and the tip; they override the arrays
_NAMED = {"m_elbow": "m_elbow", "j_elbow": "J_elbow", "mu_elbow": "mu_elbow",
          "c_elbow": "c_elbow", "elbow_flex": "elbow_flex", "m_tip": "m_tip",
          "j_tip": "J_tip", "mu_tip": "mu_tip", "c_tip": "c_tip"}


@dataclass(frozen=True)
class Published:
    """Published values a deck reproduces (group &published)."""

    table: str
    row: str
    values: dict[str, tuple[float, int]]  # quantity -> (value, decimal digits)
    deviations: tuple[str, ...] = ()
    note: str = ""


@dataclass(frozen=True)
class Deck:
    """A parsed and validated deck."""

    path: Path
    task: str
    output: str
    model: Model
    load: Load
    wrt: tuple[str, ...] = ()
    shape_points: int = 101
    tol: float | None = None
    published: tuple[Published, ...] = field(default_factory=tuple)
    fe: dict = field(default_factory=lambda: dict(FE_DEFAULTS))
    #: task simulate: ``t_out`` (array) and the keyword arguments of beamid.simulate
    simulate: dict | None = None

    @property
    def output_prefix(self) -> Path:
        """Output prefix resolved against the deck's folder."""
        out = Path(self.output)
        return out if out.is_absolute() else self.path.parent / out


def parse_published(path: Path, items: list) -> tuple[Published, ...]:
    """The &published groups of a deck (any task)."""
    published = []
    for item in items:
        quantities = [str(q) for q in _as_list(item.get("quantity", []))]
        vals = _as_list(item.get("value", []))
        digits = _as_list(item.get("digits", []))
        if not (len(quantities) == len(vals) == len(digits)) or not quantities:
            raise InputError(f"{path}: &published needs equally long quantity, value and "
                             "digits lists")
        published.append(Published(
            table=str(item.get("table", "")), row=str(item.get("row", "")),
            values={q: (float(v), int(dg)) for q, v, dg in zip(quantities, vals, digits)},
            deviations=tuple(str(d) for d in _as_list(item.get("deviation", [])) if d),
            note=str(item.get("note", "") or "")))
    return tuple(published)


def _point_name(nbeams: int, k: int) -> str:
    if k == nbeams:
        return "tip"
    return "elbow" if k == 1 else f"joint{k}"


def _as_list(value: Any) -> list:
    if value is None:
        return []
    return list(value) if isinstance(value, (list, tuple)) else [value]


def _number(path: Path, group: str, name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{path}: in &{group}: {name} = {value!r}, expected a number")
    return float(value)


def read_deck(path: str | os.PathLike):
    """Read and validate a deck; raise InputError naming the file and field.

    Estimation decks (tasks fit, compare, diagnose, improve) are returned as
    :class:`beamid.fit_decks.FitDeck`; the others as :class:`Deck`."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"cannot open {path}: no such file")
    parser = f90nml.Parser()
    try:
        nml = parser.read(str(path))
    except Exception as exc:  # f90nml raises several types for syntax errors
        raise InputError(f"{path}: not a valid namelist deck: {exc}") from None
    head_group = nml.get("beamid")
    if isinstance(head_group, dict) and str(head_group.get("task", "")) in ESTIMATION_TASKS:
        from .fit_decks import read_fit_deck

        return read_fit_deck(path)
    groups: dict[str, list[dict]] = {}
    for name, group in nml.items():
        if name not in GROUPS:
            raise InputError(f"{path}: unknown group &{name}, expected one of: "
                             f"{' '.join(GROUPS)}")
        items = group if isinstance(group, list) else [group]
        for item in items:
            for var in item:
                if var not in GROUPS[name]:
                    raise InputError(f"{path}: in &{name}: unknown variable {var!r} "
                                     f"(known: {', '.join(sorted(GROUPS[name]))})")
        groups.setdefault(name, []).extend(items)
    for name, items in groups.items():
        if len(items) > 1 and name != "published":
            raise InputError(f"{path}: group &{name} appears {len(items)} times")

    head = groups.get("beamid", [None])[0]
    if head is None:
        raise InputError(f"{path}: group &beamid is missing")
    task = str(head.get("task", "static"))
    if task not in TASKS:
        raise InputError(f"{path}: &beamid task = {task!r}, expected one of {TASKS}")
    for name in groups:
        if name == "simulate" and task != "simulate":
            raise InputError(f'{path}: group &simulate is only for task "simulate"')
        if name in ("fe", "static") and task == "simulate":
            raise InputError(f'{path}: group &{name} is not used by task "simulate" (give '
                             'elements_per_beam in &simulate)')
    output = head.get("output")
    if not output:
        raise InputError(f"{path}: &beamid output is missing: give the output path prefix")
    preset = head.get("preset") or ""
    nbeams = int(head.get("nbeams", 0) or 0)
    if preset:
        nb_preset, base = _core.preset(str(preset))
        nbeams = nbeams or nb_preset
        if nbeams != nb_preset:
            raise InputError(f"{path}: &beamid nbeams = {nbeams} but preset {preset!r} "
                             f"has {nb_preset} beams")
        values = {n: float(v) for n, v in zip(_core.param_names(nbeams), base)}
    else:
        if nbeams < 1:
            raise InputError(f"{path}: &beamid nbeams = {nbeams}: give nbeams >= 1 or a "
                             "preset (\"pace\", \"cantilever\")")
        values = {n: (0.0 if not n.startswith(("L", "EI", "EA", "rho")) else math.nan)
                  for n in _core.param_names(nbeams)}
        values["axial_coupling"] = 1.0
        values["r_motor"] = 1.0

    model_group = groups.get("model", [None])[0]
    if model_group is None and not preset:
        raise InputError(f"{path}: group &model is missing")
    named = {}
    for var, value in (model_group or {}).items():
        if var in _NAMED:
            if var.endswith("elbow") or var == "elbow_flex":
                if nbeams < 2:
                    raise InputError(f"{path}: &model sets an elbow parameter but the chain "
                                     "has one beam")
            named[_NAMED[var]] = _number(path, "model", var, value)
        elif var in _PER_BEAM or var in _PER_POINT or var == "joint_flex":
            entries = _as_list(value)
            size = nbeams - 1 if var == "joint_flex" else nbeams
            if len(entries) > size:
                raise InputError(f"{path}: in &model: {var} has {len(entries)} values, "
                                 f"expected at most {size} for {nbeams} beams")
            for k, entry in enumerate(entries, start=1):
                if entry is None:
                    continue
                if var in _PER_BEAM:
                    pname = _PER_BEAM[var].format(k)
                elif var in _PER_POINT:
                    pname = _PER_POINT[var].format(_point_name(nbeams, k))
                else:
                    pname = f"{_point_name(nbeams, k)}_flex"
                values[pname] = _number(path, "model", f"{var}({k})", entry)
        else:
            values[var] = _number(path, "model", var, value)
    values.update(named)
    for name, value in values.items():
        if math.isnan(value):
            raise InputError(f"{path}: &model is missing {name} (set it in &model, or use "
                             "a preset)")
    try:
        model = Model(nbeams, [values[n] for n in _core.param_names(nbeams)])
    except InputError as exc:
        raise InputError(f"{path}: &{exc}") from None

    load_group = groups.get("load", [None])[0]
    if load_group is None and task == "fe_modes":
        load_group = {"kind": "tip"}
    if load_group is None:
        raise InputError(f"{path}: group &load is missing")
    kind = str(load_group.get("kind", ""))
    nums = {k: _number(path, "load", k, load_group[k])
            for k in ("fx", "fy", "moment", "wire_length") if k in load_group}
    if kind == "tip":
        if "wire_length" in nums:
            raise InputError(f"{path}: &load kind = \"tip\" does not take wire_length")
        load: Load = TipLoad(nums.get("fx", 0.0), nums.get("fy", 0.0), nums.get("moment", 0.0))
    elif kind == "wire":
        if "wire_length" not in nums:
            raise InputError(f"{path}: &load kind = \"wire\" needs wire_length (m)")
        if any(nums.get(k, 0.0) != 0.0 for k in ("fx", "fy", "moment")):
            raise InputError(f"{path}: &load kind = \"wire\" does not take fx, fy or moment")
        load = RadialWire(nums["wire_length"])
    else:
        raise InputError(f"{path}: &load kind = {kind!r}, expected \"tip\" or \"wire\"")
    simulate = None
    if task == "simulate":
        simulate = _simulate_group(path, load, groups.get("simulate", [None])[0])

    static = groups.get("static", [{}])[0]
    wrt = tuple(str(w) for w in _as_list(static.get("wrt", [])) if w)
    for w in wrt:
        try:
            model.index(w)
        except InputError:
            raise InputError(f"{path}: &static wrt = {w!r} is not a parameter name "
                             "(e.g. EI1, C2, elbow_flex)") from None
    shape_points = int(static.get("shape_points", 101))
    if shape_points < 0 or shape_points == 1:
        raise InputError(f"{path}: &static shape_points = {shape_points}, expected 0 (no "
                         "shape) or at least 2")
    tol = float(static.get("tol", 0.0))
    if not (0.0 <= tol < 1e-2):
        raise InputError(f"{path}: &static tol = {tol}, expected 0 (default) or a "
                         "tolerance below 1e-2")

    fe = dict(FE_DEFAULTS)
    for key, value in groups.get("fe", [{}])[0].items():
        fe[key] = value
    if int(fe["elements_per_beam"]) < 1:
        raise InputError(f"{path}: &fe elements_per_beam = {fe['elements_per_beam']}, "
                         "expected at least 1")
    if fe["moment_form"] not in ("eq78", "exact"):
        raise InputError(f"{path}: &fe moment_form = {fe['moment_form']!r}, expected "
                         "\"eq78\" or \"exact\"")
    if int(fe["steps"]) < 0 or float(fe["tol"]) < 0:
        raise InputError(f"{path}: &fe steps and tol must not be negative (0: default)")
    if task.startswith("fe_") and isinstance(load, RadialWire):
        raise InputError(f"{path}: &load kind = \"wire\" is not available for task "
                         f"{task!r} (tip loads only)")

    published = parse_published(path, groups.get("published", []))
    return Deck(path=path, task=task, output=str(output), model=model, load=load, wrt=wrt,
                shape_points=shape_points, tol=tol or None, published=published,
                fe=fe, simulate=simulate)


def _simulate_group(path: Path, load: Load, group: dict | None) -> dict:
    """Validate &simulate (the checks and messages of beamid-batch, in its
    order) and return ``t_out`` and the keyword arguments of beamid.simulate."""
    if isinstance(load, RadialWire):
        raise InputError(f'{path}: &load kind = "wire" is not available for task "simulate" '
                         "(tip loads only)")
    if group is None:
        raise InputError(f"{path}: group &simulate is missing")
    given = dict(group)
    times = _as_list(given.get("t_out", []))
    while times and times[-1] is None:
        times.pop()
    if any(t is None for t in times):
        raise InputError(f"{path}: &simulate t_out has gaps: give the output times as one list")
    times = [_number(path, "simulate", "t_out", t) for t in times]
    t_end = given.get("t_end")
    if times and t_end is not None:
        raise InputError(f"{path}: &simulate gives both t_out and t_end: give one")
    if not times and t_end is None:
        raise InputError(f"{path}: &simulate needs t_out (a list of output times) or t_end "
                         "(with n_out)")
    if times and "n_out" in given:
        raise InputError(f"{path}: &simulate n_out goes with t_end, not with t_out")
    if times:
        t_out = np.array(times, dtype=float)
    else:
        t_end = _number(path, "simulate", "t_end", t_end)
        if not (0.0 < t_end < math.inf):
            raise InputError(f"{path}: &simulate t_end = {t_end:g}, expected a time > 0 (s)")
        n_out = _integer(path, "simulate", "n_out", given.get("n_out", DEFAULT_N_OUT))
        if n_out < 2:
            raise InputError(f"{path}: &simulate n_out = {n_out}, expected at least 2")
        t_out = np.linspace(0.0, t_end, n_out)
    bad = [k for k, t in enumerate(t_out)
           if not math.isfinite(t) or (k == 0 and t < 0) or (k > 0 and t <= t_out[k - 1])]
    if bad:
        raise InputError(f"{path}: &simulate t_out must be ascending times >= 0 (entry "
                         f"{bad[0] + 1} = {t_out[bad[0]]:g})")
    opts = dict(SIMULATE_DEFAULTS)
    nel = _integer(path, "simulate", "elements_per_beam",
                   given.get("elements_per_beam", opts["elements_per_beam"]))
    if nel < 1:
        raise InputError(f"{path}: &simulate elements_per_beam = {nel}, expected at least 1")
    opts["elements_per_beam"] = nel
    integrator = str(given.get("integrator", opts["integrator"]))
    if integrator not in ("implicit", "rk4"):
        raise InputError(f'{path}: &simulate integrator = "{integrator}", expected "implicit" '
                         'or "rk4"')
    opts["integrator"] = integrator
    friction = str(given.get("friction", "") or "")
    if friction not in ("", "sign", "smooth", "sign_literal"):
        raise InputError(f'{path}: &simulate friction = "{friction}", expected "sign", '
                         '"smooth" or "sign_literal"')
    opts["friction"] = friction or "sign"
    for name in ("dt", "rtol", "atol", "friction_velocity"):
        value = _number(path, "simulate", name, given.get(name, 0.0))
        if not 0.0 <= value < math.inf:
            raise InputError(f"{path}: &simulate {name} = {value:g}, expected 0 (default) or "
                             "a positive number")
        opts[name] = value or None
    gain = _number(path, "simulate", "motor_gain", given.get("motor_gain", 0.0))
    if not 0.0 <= gain < math.inf:
        raise InputError(f"{path}: &simulate motor_gain = {gain:g}, expected a finite number "
                         ">= 0")
    opts["motor_gain"] = gain
    return {"t_out": t_out, **opts}


def _integer(path: Path, group: str, name: str, value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise InputError(f"{path}: in &{group}: {name} = {value!r}, expected an integer")
    return int(value)


def write_deck(deck: Deck, path: str | os.PathLike) -> None:
    """Write a deck that reads back to the same model, load and options."""
    model = deck.model
    nb = model.nbeams
    p = model.params
    groups: dict[str, dict[str, Any]] = {
        "beamid": {"task": deck.task, "output": deck.output, "nbeams": nb},
        "model": {
            **{var: [p[fmt.format(k)] for k in range(1, nb + 1)]
               for var, fmt in _PER_BEAM.items()},
            **{var: [p[fmt.format(_point_name(nb, k))] for k in range(1, nb + 1)]
               for var, fmt in _PER_POINT.items()},
            **({"joint_flex": [p[f"{_point_name(nb, k)}_flex"] for k in range(1, nb)]}
               if nb > 1 else {}),
            **{g: p[g] for g in _GLOBAL},
        },
    }
    if isinstance(deck.load, RadialWire):
        groups["load"] = {"kind": "wire", "wire_length": deck.load.Lw}
    else:
        groups["load"] = {"kind": "tip", "fx": deck.load.fx, "fy": deck.load.fy,
                          "moment": deck.load.moment}
    static: dict[str, Any] = {"shape_points": deck.shape_points}
    if deck.wrt:
        static["wrt"] = list(deck.wrt)
    if deck.tol:
        static["tol"] = deck.tol
    groups["static"] = static
    nml = f90nml.Namelist(groups)
    nml.float_format = ".17g"
    _atomic_write(Path(path), str(nml) + "\n")


def _run_fe(deck: Deck):
    """fe_static: <output>_summary.csv and _nodes.csv; fe_modes: <output>_modes.csv
    (the files beamid-batch writes)."""
    from . import fe

    opts = deck.fe
    prefix = deck.output_prefix
    if deck.task == "fe_static":
        r = fe.fe_static(deck.model, deck.load, int(opts["elements_per_beam"]),
                         moment_form=str(opts["moment_form"]), steps=int(opts["steps"]),
                         tol=float(opts["tol"]))
        names = ("w_tip", "dw_tip", "u_tip", "du_tip", "du_root", "energy", "x_tip", "y_tip")
        values = fe.evaluate_fe("fe_static", deck.model, deck.load,
                                elements_per_beam=int(opts["elements_per_beam"]),
                                moment_form=str(opts["moment_form"]), steps=int(opts["steps"]),
                                tol=float(opts["tol"]), quantities=names)
        lines = ["quantity,value"] + [f"{n},{_csv_number(values[n])}" for n in names]
        lines += [f"newton_iterations,{r.iterations}", f"load_steps,{r.steps}"]
        _atomic_write(Path(f"{prefix}_summary.csv"), "\n".join(lines) + "\n")
        table = np.column_stack([r.nodes[k] for k in ("s", "u", "du", "w", "dw")])
        rows = ["s,u,du,w,dw"] + [",".join(_csv_number(v) for v in row) for row in table]
        _atomic_write(Path(f"{prefix}_nodes.csv"), "\n".join(rows) + "\n")
        return r
    md = fe.modes(deck.model, int(opts["elements_per_beam"]),
                  rotary_inertia=bool(opts["rotary_inertia"]))
    lines = ["quantity,value"]
    lines += [f"omega_w{i},{_csv_number(w)}" for i, w in enumerate(md.transverse, start=1)]
    lines += [f"omega_u{i},{_csv_number(w)}" for i, w in enumerate(md.axial, start=1)]
    _atomic_write(Path(f"{prefix}_modes.csv"), "\n".join(lines) + "\n")
    return md


def history_columns(nbeams: int) -> tuple[str, ...]:
    """Columns of ``<output>_history.csv`` (task simulate), as beamid-batch
    writes them: time, tip, energies, each work line, their sum, the
    numerical line E - E0 - work, the motor torque."""
    from .dynamics import work_names

    return ("t", "tip_u", "tip_w", "tip_angle", "energy", "kinetic", "potential",
            *work_names(nbeams), "work", "numerical", "motor_torque")


def history_table(run, nbeams: int) -> np.ndarray:
    """The rows of ``<output>_history.csv`` of a :class:`beamid.Run` (nt, ncol)."""
    from .dynamics import work_names

    cols = [run.t, run.tip_u, run.tip_w, run.tip_angle, run.energy, run.ledger["kinetic"],
            run.ledger["potential"], *[run.ledger[n] for n in work_names(nbeams)], run.work,
            run.ledger["numerical"], run.motor_torque]
    return np.column_stack(cols)


def _run_simulate(deck: Deck):
    """simulate: <output>_history.csv (the file beamid-batch writes)."""
    from .dynamics import simulate

    opts = dict(deck.simulate or {})
    t_out = opts.pop("t_out")
    run = simulate(deck.model, deck.load, t_out, **opts)
    nb = deck.model.nbeams
    rows = [",".join(history_columns(nb))]
    rows += [",".join(_csv_number(v) for v in row) for row in history_table(run, nb)]
    _atomic_write(Path(f"{deck.output_prefix}_history.csv"), "\n".join(rows) + "\n")
    return run


def _atomic_write(path: Path, text: str) -> None:
    """Write text to path through a temporary file, so no half file is left."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as handle:
            handle.write(text)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _csv_number(x: float) -> str:
    return f"{x:.16E}"


def run(deck: Deck | str | os.PathLike):
    """Run a deck as ``beamid-batch`` does and write the same CSV files.

    Static decks write ``<output>_summary.csv`` (outputs and sensitivities) and
    ``<output>_shape.csv``; dynamic decks ``<output>_history.csv``; finite element
    and estimation decks the files listed in docs/decks.md. Returns the result
    object of the task (a :class:`beamid.Run` for simulate).
    """
    if not isinstance(deck, Deck):
        deck = read_deck(deck)
    if deck.task in ESTIMATION_TASKS:
        from .fit_decks import run_fit_deck

        return run_fit_deck(deck)[2]
    if deck.task.startswith("fe_"):
        return _run_fe(deck)
    if deck.task == "simulate":
        return _run_simulate(deck)
    result = solve_static(deck.model, deck.load, wrt=deck.wrt, tol=deck.tol)
    shape = result.shape(n=deck.shape_points) if deck.shape_points >= 2 else None
    names = ("x_tip", "y_tip", "tip_angle", "wire_force", "x_elbow", "y_elbow",
             "elbow_angle", "root_moment")
    lines = ["quantity,value"]
    lines += [f"{n},{_csv_number(result.outputs[o])}" for n, o in zip(names, OUTPUTS)]
    for p in deck.wrt:
        canonical = deck.model.names()[deck.model.index(p)]
        lines += [f"d({n})/d({canonical}),{_csv_number(result.d[o][p])}"
                  for n, o in zip(names, OUTPUTS)]
    lines += [f"newton_iterations,{result.newton_iterations}",
              f"load_steps,{result.load_steps}"]
    prefix = deck.output_prefix
    _atomic_write(Path(f"{prefix}_summary.csv"), "\n".join(lines) + "\n")
    if shape is not None:
        rows = ["s,x,y,psi,moment"] + [",".join(_csv_number(v) for v in row)
                                       for row in np.column_stack(shape)]
        _atomic_write(Path(f"{prefix}_shape.csv"), "\n".join(rows) + "\n")
    return result
