"""Property-based fuzz of the public Python API (issue 32), run as a program
by tests/test_fuzz_api.py (in a subprocess, so that a crash of the process,
a signal, fails that test instead of killing pytest).

Property: every public callable of beamid (each callable name of
``beamid.__all__`` found by introspection, and the public methods and
properties of the objects they return) given one bad argument around a
cheap valid call returns or raises a ``beamid.BeamidError``; never another
exception, never a signal.

- The callables are discovered, not listed: a new public function joins by
  being in ``beamid.__all__``, a new method by being public on a result.
- A valid call is made of examples chosen by parameter name (``VALID``; a
  name that means different things in different places has an entry
  ``"callable.parameter"`` in ``OVERRIDE``). A parameter with a default
  keeps it unless ``OVERRIDE`` makes the call cheaper. A public callable
  with a required parameter that has no example fails the run (add one).
- Each example replaces one argument by a drawn bad value: wrong types,
  None, strings, negative and huge counts, NaN and infinities, empty,
  ragged and nested arrays, and the valid objects of other parameters.
- Numbers are drawn small (|x| <= 4), extreme (NaN, +-inf, 1e+-300) or
  huge (>= 2**31), never in between: a valid but large mesh or time span
  would only make the call slow, not wrong.

Run ``python tests/fuzz_api.py --profile default|long --report FILE``; the
report is JSON: the failures (callable, argument, value, exception) and
counts. ``--progress FILE`` names the call in flight (read after a crash).
"""
from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import inspect
import json
import math
import os
import sys
import tempfile
import time
import traceback
from pathlib import Path

import numpy as np

os.environ.setdefault("MPLBACKEND", "Agg")

import beamid  # noqa: E402
from hypothesis import HealthCheck, Phase, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

#: examples per callable (drawn after the fixed grid of CORE values)
PROFILES = {"default": 6, "long": 150}

#: names of beamid.__all__ left out by hand, each with its reason: none today
#: (exception classes, aliases and result records are found by introspection
#: and listed in the report's "skipped" with theirs)
SKIP: dict[str, str] = {}

#: callables that need an optional package, left out (with the reason) when it
#: is not installed: no valid call exists without it
NEEDS = {"Measurements.to_frame": "pandas"}


class _Frame:
    """A pandas DataFrame stand-in (pandas is optional): columns and [name]."""

    def __init__(self, columns: dict):
        self._columns = columns
        self.columns = list(columns)

    def __getitem__(self, name):
        return self._columns[name]

    def __repr__(self) -> str:
        return f"<frame {self.columns}>"


class _Opaque:
    """An object of no expected type."""

    def __repr__(self) -> str:
        return "<opaque object>"


nan, inf = math.nan, math.inf
#: the fixed grid: every parameter of every callable gets each of these
CORE = [None, "abc", -1, 2**31, nan, inf, [], [[1.0], [1.0, 2.0]], _Opaque()]
#: more values the draws pick from
EXTRA = [True, False, 0, 1, 2, -2**31 - 1, 2**63, 10**30, 0.0, -0.0, -1.5, 0.5, 2.5, 1e-300,
         1e300, -inf, "", "1.5", "EI1", b"x", 1 + 2j, [nan], [inf, 1.0], [-1.0], ["a", "b"],
         [None], (1, 2, 3), {"a": 1}, {}, set(), [1, "a"], np.float64(nan), np.int64(-1),
         np.array([]), np.zeros((2, 2)), np.array([nan]), np.array(["x"]), [[]], [0.5, nan],
         {"EI1": nan}, {"F2": "y_tip"}, ("EI9",), ("EI1", "EI1"), -(10**30)]


#: parameters that are times (s): a huge finite time is valid but means a long run,
#: so their draws keep finite numbers small (NaN, infinities and wrong types stay)
TIME_PARAMS = {"t_out", "t", "times"}


#: draws left out for one parameter: valid values that are expensive, with the reason
EXPENSIVE = {
    "reproduce.tables": ("an empty list reproduces every published table (about a minute)",
                         lambda v: hasattr(v, "__len__") and not isinstance(v, str)
                         and len(v) == 0),
}


def _bounded(value) -> bool:
    """No finite number beyond 4 in magnitude (for TIME_PARAMS)."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        return True
    finite = arr[np.isfinite(arr)] if arr.dtype.kind == "f" else arr
    return not np.any(np.abs(finite) > 4.0)


def small_float():
    return st.floats(min_value=-4.0, max_value=4.0, allow_nan=False)


def bad_values(pool: list) -> st.SearchStrategy:
    """Wrong types, None, strings, negative and huge counts, NaN and
    infinities, empty, ragged and nested arrays, other parameters' objects."""
    numbers = st.one_of(st.integers(-4, 4), st.integers(2**31, 2**80),
                        st.integers(-2**80, -2**31), small_float(),
                        st.sampled_from([nan, inf, -inf, 1e300, -1e300, 1e-300]))
    scalars = st.one_of(numbers, st.none(), st.booleans(), st.text(max_size=4))
    return st.one_of(
        st.sampled_from(CORE + EXTRA),
        scalars,
        st.lists(st.one_of(numbers, st.text(max_size=2), st.none()), max_size=4),
        st.lists(st.lists(small_float(), max_size=3), max_size=3),
        st.lists(numbers, max_size=4).map(tuple),
        st.lists(numbers, min_size=1, max_size=4).map(np.array),
        st.dictionaries(st.text(max_size=4), scalars, max_size=2),
        st.sampled_from(pool),
    )


# ----------------------------------------------------------------- valid calls

class Env:
    """The cheap valid objects the calls are made of (built once)."""

    def __init__(self, work: Path):
        self.work = work
        self.model = beamid.pace()
        self.load = beamid.TipForce(fy=2.0)
        self.exps = {"F2": beamid.TipForce(fy=2.0), "F4": beamid.TipForce(fy=4.0)}
        self.data = beamid.simulate_measurements(self.model, self.exps, ["y_tip", "x_tip"],
                                                 sigma=1e-3, noise=True, seed=1)
        self.fit = beamid.fit(self.model, self.exps, self.data, free=("EI1",))
        release = beamid.Release(beamid.TipForce(fy=2.0), elements_per_beam=2)
        self.dyn_exps = {"R2": release}
        self.dyn_data = beamid.simulate_measurements(self.model, self.dyn_exps, ["w_tip"],
                                                     sigma=1e-3, t=[0.01, 0.02])
        self.dyn_fit = beamid.fit(self.model, self.dyn_exps, self.dyn_data, free=("EI1",))
        (work / "out").mkdir(exist_ok=True)
        self.deck_path = work / "static.nml"
        self.deck_path.write_text(
            "&beamid\n  task = 'static'\n  output = 'out/s'\n  preset = 'pace'\n/\n"
            "&load\n  kind = 'tip'\n  fy = 2.0\n/\n&static\n  shape_points = 5\n/\n")
        self.csv_path = work / "data.csv"
        self.data.write(self.csv_path)
        self.loads_csv = work / "loads.csv"
        self.loads_csv.write_text("t,tip_fy\n0.0,0.0\n0.01,1.0\n")
        self.logger_csv = work / "logger.csv"
        self.logger_csv.write_text("t,y_tip,strain@1:0.05\n0.0,0.1,1e-3\n0.01,0.2,2e-3\n")
        self.deck = beamid.read_deck(self.deck_path)
        self.fe = beamid.fe_static(self.model, self.load, 4)
        self.pairing = beamid.pair_modes([1.0, 2.0], None, [1.1, 2.1, 3.0], None)
        self.uff_path = work / "modes.uff"
        _write_uff(self.uff_path)
        self.effect = beamid.Effect("fuzz_effect", "a registered effect of the fuzz",
                                    lambda m: ("root_flex",))


def _write_uff(path: Path) -> None:
    """A small UFF file of two modes at nodes 1, 2 (pyuff writes it; without
    pyuff an empty file, and read_uff's calls say pyuff is missing)."""
    try:
        import pyuff
    except ImportError:
        path.write_text("")
        return
    sets = [pyuff.prepare_55(model_type=1, id1="fuzz", id2="NONE", id3="NONE", id4="NONE",
                             id5="NONE", analysis_type=2, data_ch=2, spec_data_type=8,
                             data_type=2, n_data_per_node=3, r1=np.zeros(2),
                             r2=np.array([0.3, 1.0]) * (1 - 2 * k), r3=np.zeros(2),
                             node_nums=[1, 2], load_case=1, mode_n=k + 1, modal_m=0,
                             freq=0.4 + k, modal_damp_vis=0.01, modal_damp_his=0.0)
            for k in range(2)]
    pyuff.UFF(str(path)).write_sets(sets, mode="overwrite")


def valid_examples(env: Env) -> tuple[dict, dict]:
    """(VALID by parameter name, OVERRIDE by 'callable.parameter')."""
    valid = {
        "model": env.model, "load": env.load, "release": env.load, "load0": env.load,
        "dload": env.load, "experiments": env.exps, "data": env.data, "fit": env.fit,
        "free": ("EI1",), "nbeams": 1, "values": beamid.cantilever().vector(),
        "fx": 1.0, "fy": 1.0, "moment": 1.0, "Lw": 1.3, "path": env.deck_path,
        "deck": env.deck_path, "t_out": [0.0, 0.005], "quantities": ["y_tip"],
        "stages": {"s1": (env.exps, env.data, ("EI1",))}, "effect": "elbow_flex",
        "name": "EI1", "names": ("EI1",), "overrides": {"EI1": 11.0}, "i": 1, "k": 1,
        "value": 1.0, "times": 0.0, "factor": 2.0, "experiment": ("F2",), "t": [0.0],
        "quantity": ("y_tip",), "sigma": [1e-3], "description": "a fuzz effect",
        "params": lambda m: ("root_flex",), "rows": [("F2", 0.0, "y_tip", 0.1, 1e-3)],
        "other": beamid.Measurements.from_rows([("F9", 0.0, "y_tip", 0.1, 1e-3)]),
        "key": ("M1", "y_tip"), "shape": env.fe, "target": "EI1",
        "peak": 1.0, "duration": 0.01, "amplitude": 1.0, "f0": 1.0, "f1": 2.0,
        "w_s": 1.0, "T": 1.0,
        "a": np.eye(3), "b": np.eye(3)[:, :2], "measured_freq": [1.0, 2.0],
        "measured_shapes": [[1.0, 0.0], [0.0, 1.0], [0.1, 0.1]],
        "model_freq": [1.1, 2.1, 3.0], "model_shapes": np.eye(3), "measured": 1,
        "pairing": env.pairing, "nmodes": 2, "stations": ("shape_n@1:0.4", "shape_psi@2:0.3"),
        "freq": [0.4, 1.7], "shapes": [[1.0, 0.2], [0.5, -1.0]],
    }
    override = {
        "read_measurements.path": env.csv_path,
        "write_deck.deck": env.deck,
        "write_deck.path": env.work / "out" / "deck.nml",
        "write.path": env.work / "out" / "data.csv",
        "to_csv.path": env.work / "out" / "mc.csv",
        "simulate.elements_per_beam": 2,
        "simulate.release": env.load,
        "simulate.t_out": [0.0, 0.005],
        "design.target": "EI1",
        "design.candidates": {"M1": beamid.TipMoment(1.0)},
        "diagnose.candidates": ("elbow_flex",),
        "diagnose.nrefit": 1,
        "fit.starts": 0,            # the one fit: a drawn 1 or 2 still runs more starts
        "improve.candidates": ("elbow_flex",),
        "improve.free": ("EI1",),
        "add_effect.effect": "elbow_flex",
        "register_effect.effect": env.effect,
        "Effect.name": "fuzz_effect2",
        "consistency.replicates": 2,
        "consistency.workers": 1,
        "reproduce.tables": ("2",),
        "with_values.value": [0.1] * len(env.data),
        "check_experiments.experiments": env.exps,
        "decode.values": beamid.Release(beamid.TipForce(fy=1.0)).encode()[1],
        "from_spec.spec": beamid.Release(beamid.TipForce(fy=1.0)).spec()[1],
        "Release.load": env.load,
        "Release.elements_per_beam": 2,
        "modal_cost.t": 0.1,
        "fe_path.max_points": 5,
        "fe_path.elements_per_beam": 2,
        "fe_static.elements_per_beam": 4,
        "buckling_load.elements_per_beam": 2,
        "modes.elements_per_beam": 4,
        "axial_modes_linear.elements_per_beam": 2,
        "profiles.points_per_element": 2,
        "plot.top": 3,
        "Measurements.value": [0.1],
        "Table.times": [0.0, 0.01],
        "Table.values": [0.0, 1.0],
        "from_csv.path": env.loads_csv,
        "from_csv.column": "tip_fy",
        "Sensor.observation": "strain@1:0.05",
        "read_channels.source": env.logger_csv,
        "read_channels.experiment": "free",
        "read_channels.sigma": 1e-3,
        "changes.other": env.pairing,
        "modal_rows.experiment": "M0",
        "modal_rows.stations": ("shape_n@1:0.4", "shape_n@2:0.7"),
        "read_uff.path": env.uff_path,
        "read_uff.experiment": "M0",
        "read_uff.stations": {1: "shape_n@1:0.4", 2: "shape_n@2:0.7"},
        "Modal.load": env.load,
        "Modal.elements_per_beam": 2,
        "modal_analysis.elements_per_beam": 2,
        "modal_analysis.wrt": ("EI1", "rho1"),
        "from_frame.frame": _Frame({"experiment": ["F2"], "t": [0.0], "quantity": ["y_tip"],
                                    "value": [0.1], "sigma": [1e-3]}),
    }
    return valid, override


# ----------------------------------------------------------------- discovery

@dataclasses.dataclass
class Target:
    label: str                  #: e.g. "beamid.fit" or "FitResult.summary"
    func: object                #: the callable
    short: str                  #: name for OVERRIDE keys (function or method name)
    params: list                #: inspect.Parameter list (no self)
    owner: str = ""             #: class name for methods / constructors


def _is_record(cls: type) -> bool:
    """A result type whose constructor only stores its fields (a dataclass
    without __post_init__, a NamedTuple, a class whose __init__ only assigns):
    beamid makes it, the fuzz calls its methods on real ones."""
    if issubclass(cls, tuple) and hasattr(cls, "_fields"):
        return True
    if dataclasses.is_dataclass(cls) and not hasattr(cls, "__post_init__"):
        return True
    return False


def _params(func) -> list:
    try:
        sig = inspect.signature(func)
    except (TypeError, ValueError):
        return []
    return [p for p in sig.parameters.values() if p.kind is not p.VAR_POSITIONAL]


def public_targets() -> tuple[list[Target], list[tuple[str, str]], list[type]]:
    """(targets, skipped with reason, record classes) of beamid.__all__."""
    targets, skipped, records, seen = [], [], [], set()
    for name in beamid.__all__:
        obj = getattr(beamid, name)
        if name in SKIP:
            skipped.append((name, SKIP[name]))
            continue
        if not callable(obj):
            continue
        if isinstance(obj, type) and issubclass(obj, BaseException):
            skipped.append((name, "an exception class: raised, not called"))
            continue
        if id(obj) in seen:
            skipped.append((name, "an alias of a callable fuzzed under another name"))
            continue
        seen.add(id(obj))
        if isinstance(obj, type) and _is_record(obj):
            records.append(obj)
            skipped.append((name, "a result record (its constructor only stores fields); "
                                  "its methods are fuzzed on real results"))
            continue
        targets.append(Target(f"beamid.{name}", obj, name, _params(obj),
                              owner=name if isinstance(obj, type) else ""))
    return targets, skipped, records


def method_targets(obj) -> tuple[list[Target], list[str]]:
    """Public methods (bound) and properties of a beamid result object."""
    cls = type(obj)
    out, props = [], []
    for name in dir(cls):
        if name.startswith("_"):
            continue
        attr = inspect.getattr_static(cls, name)
        if isinstance(attr, property):
            props.append(name)
        elif isinstance(attr, (staticmethod, classmethod)) or inspect.isfunction(attr):
            bound = getattr(obj, name)
            out.append(Target(f"{cls.__name__}.{name}", bound, name, _params(bound),
                              owner=cls.__name__))
    return out, props


def _beamid_objects(value, depth: int = 0):
    """beamid objects in a result (itself, or the first items of a list,
    tuple or dict of them)."""
    if type(value).__module__.startswith("beamid"):
        yield value
    if depth < 1 and isinstance(value, (list, tuple)) and value and \
            not type(value).__module__.startswith("beamid"):
        yield from _beamid_objects(value[0], depth + 1)


# ----------------------------------------------------------------- calling

class Fuzz:
    def __init__(self, env: Env, progress: Path | None):
        self.env = env
        self.valid, self.override = valid_examples(env)
        self.pool = [env.model, env.load, env.exps, env.data, env.fit, env.deck,
                     beamid.RadialWire(1.3), env.dyn_exps["R2"], _Opaque()]
        self.progress = progress
        self.failures: dict[tuple, dict] = {}
        self.calls = 0
        self.errors = 0

    def example(self, t: Target, p: inspect.Parameter):
        """A valid value of parameter p of t (KeyError: none)."""
        for key in (f"{t.short}.{p.name}", f"{t.owner}.{p.name}"):
            if key in self.override:
                return self.override[key]
        return self.valid[p.name]

    def baseline(self, t: Target) -> dict:
        kwargs = {}
        for p in t.params:
            if p.kind is p.VAR_KEYWORD:
                continue
            keys = (f"{t.short}.{p.name}", f"{t.owner}.{p.name}")
            if p.default is p.empty or any(k in self.override for k in keys):
                kwargs[p.name] = self.example(t, p)
        return kwargs

    def _note(self, text: str) -> None:
        if self.progress is not None:
            self.progress.write_text(text + "\n")

    def call(self, t: Target, kwargs: dict, what: str):
        """Call; a BeamidError is fine, another exception a failure."""
        self.calls += 1
        self._note(f"{t.label}({what})")
        positional = [kwargs.pop(p.name) for p in t.params
                      if p.kind is p.POSITIONAL_ONLY and p.name in kwargs]
        extra = kwargs.pop("**", {})
        try:
            result = t.func(*positional, **kwargs, **extra)
            if "matplotlib.pyplot" in sys.modules:
                sys.modules["matplotlib.pyplot"].close("all")
            return True, result
        except beamid.BeamidError as exc:
            self.errors += 1
            self.last_error = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            return False, None
        except Exception as exc:  # noqa: BLE001 - the property under test
            frame = traceback.extract_tb(exc.__traceback__)[-1]
            key = (t.label, what.split("=")[0], type(exc).__name__)
            self.failures.setdefault(key, {
                "callable": t.label, "call": what, "exception": type(exc).__name__,
                "message": str(exc)[:300],
                "where": f"{Path(frame.filename).name}:{frame.lineno} ({frame.name})"})
            return False, None

    def mutate(self, t: Target, base: dict, p: inspect.Parameter, value) -> None:
        kwargs = dict(base)
        if p.kind is p.VAR_KEYWORD:
            if isinstance(value, str):
                kwargs["**"] = {value or "x": 1.0}
                what = f"**{{{value!r}: 1.0}}"
            else:
                kwargs["**"] = {"EI1": value}
                what = f"**{{'EI1': {_short(value)}}}"
        else:
            kwargs[p.name] = value
            what = f"{p.name}={_short(value)}"
        ok, result = self.call(t, kwargs, what)
        if ok:
            for obj in _beamid_objects(result):
                _, props = method_targets(obj)
                for name in props:
                    self._property(obj, name, f"{t.label}({what})")

    def _property(self, obj, name: str, origin: str) -> None:
        t = Target(f"{type(obj).__name__}.{name}", lambda: getattr(obj, name), name, [])
        self.call(t, {}, f"property of {origin}"[:120])

    @staticmethod
    def allowed(t: Target, p: inspect.Parameter, value) -> bool:
        """Not a draw left out (TIME_PARAMS, EXPENSIVE)."""
        if p.name in TIME_PARAMS and not _bounded(value):
            return False
        rule = EXPENSIVE.get(f"{t.short}.{p.name}")
        return rule is None or not rule[1](value)

    def run(self, t: Target, examples: int) -> object:
        """The valid call (its result returned), the grid, then the draws."""
        base = self.baseline(t)
        ok, result = self.call(t, dict(base), "valid call")
        if not ok:
            raise KeyError(f"the valid call {_short(base, 120)} raised {self.last_error!r} "
                           "(fix its examples in VALID/OVERRIDE)")
        for p in t.params:
            for value in CORE:
                if self.allowed(t, p, value):
                    self.mutate(t, base, p, value)
        if t.params and examples:
            strategy = st.sampled_from(t.params).flatmap(
                lambda p: st.tuples(st.just(p), bad_values(self.pool).filter(
                    lambda v: self.allowed(t, p, v))))

            @settings(max_examples=examples, derandomize=True, database=None, deadline=None,
                      phases=[Phase.generate], suppress_health_check=list(HealthCheck))
            @given(strategy)
            def draw(case):
                self.mutate(t, base, *case)

            draw()
        return result


def _short(value, width: int = 80) -> str:
    try:
        text = repr(value)
    except Exception:  # noqa: BLE001
        text = f"<{type(value).__name__}>"
    return text if len(text) <= width else text[: width - 3] + "..."


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--profile", default=os.environ.get("BEAMID_FUZZ_PROFILE", "default"),
                    choices=sorted(PROFILES))
    ap.add_argument("--report", type=Path, required=True)
    ap.add_argument("--progress", type=Path)
    ap.add_argument("--only", default="", help="fuzz only labels containing this text")
    args = ap.parse_args(argv)
    import faulthandler

    faulthandler.enable()
    examples = PROFILES[args.profile]
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        os.chdir(tmp)               # files the calls write land here
        env = Env(Path(tmp))
        fuzz = Fuzz(env, args.progress)
        targets, skipped, records = public_targets()
        missing = []
        done = []

        def write_report(finished: bool) -> dict:
            """The report so far (after every callable: a crash leaves it behind)."""
            report = {
                "profile": args.profile, "finished": finished,
                "seconds": round(time.perf_counter() - t0, 1), "calls": fuzz.calls,
                "beamid_errors": fuzz.errors, "fuzzed": done, "skipped": skipped,
                "records": [c.__name__ for c in records], "missing_examples": missing,
                "failures": list(fuzz.failures.values()),
            }
            args.report.write_text(json.dumps(report, indent=1))
            return report

        queue = list(targets)
        seen_types = set()
        # the methods of the environment's own objects first (their examples fit them)
        for obj in (env.data, env.fit, env.model, env.load, env.deck, env.fe,
                    beamid.compare(env.dyn_fit)):
            seen_types.add(type(obj))
            methods, props = method_targets(obj)
            queue.extend(methods)
            for name in props:
                fuzz._property(obj, name, "environment")
        while queue:
            t = queue.pop(0)
            if args.only and args.only not in t.label:
                continue
            if t.label in NEEDS and importlib.util.find_spec(NEEDS[t.label]) is None:
                skipped.append((t.label, f"needs {NEEDS[t.label]}, not installed"))
                continue
            t1 = time.perf_counter()
            try:
                result = fuzz.run(t, examples)
            except KeyError as exc:
                missing.append(f"{t.label}: no valid example for parameter {exc}")
                continue
            done.append((t.label, round(time.perf_counter() - t1, 2)))
            for obj in _beamid_objects(result):
                if type(obj) in seen_types:
                    continue
                seen_types.add(type(obj))
                methods, props = method_targets(obj)
                queue.extend(methods)
                for name in props:
                    fuzz._property(obj, name, f"{t.label}(valid call)")
            write_report(False)
        report = write_report(True)
    return 1 if report["failures"] or missing else 0


if __name__ == "__main__":
    sys.exit(main())
