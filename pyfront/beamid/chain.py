"""The measurement chain: nuisance parameters fitted with the physics (issue 29).

A record's clock offset ``t0`` (a release's data row at record time t is
the model at time t + t0: t0 is the model time at the logger's zero, 0.015
when the logger started 15 ms after the release), and per channel
(experiment, observation: ``w_tip``, ``strain@1:0.05``) a bias ``b`` and a
scale ``s`` (the row reads s h + b). They are extra columns of the one
Gauss-Newton fit (Fortran, ``beamid_inverse``): the t0 column is s dh/dt
from the integrated state's rates (every observation kind but the
accelerations, whose records take no time offset), the bias column 1, the
scale column h; a release's initial tip normal velocity ``v0`` (the
chain starts from its static shape q with the velocity field v0 q /
w_tip(q) instead of at rest) has the column s dh/dv0 from the sensitivity
equations started at ds/dv0(0) = (0, q / w_tip(q)); the covariance of the physics parameters is the matching
block of the full inverse, so it accounts for them. Channels are numbered
by the problem's observation list (beamid.observations.ordered), at most
the first 52 of it (a channel mask is a whole number in a double).

>>> import beamid
>>> spec = parse_nuisance({"time_offset": ["free"], "bias": [("free", "w_tip")]},
...                       {"free": beamid.Release(fy=8.0)}, None)
>>> spec.names()
('t0[free]', 'bias[free:w_tip]')
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

from . import _check, _core_estimation as _ce
from ._core import _call, spec_from_column, spec_row
from .errors import InputError
from . import observations
from .loads import timed
from .measurements import _canonical

#: keys of the ``nuisance`` argument of :func:`beamid.fit`
NUISANCE_KINDS = ("time_offset", "bias", "scale", "initial_velocity")
#: channels (bits of a mask in a double) of the first entries of the
#: observation list at most (beamid_inverse MAX_CHANNEL_BITS)
MAX_CHANNEL_BITS = 52
#: kinds whose rate (the t0 column) the core does not compute: a record with
#: such rows takes no clock offset (the acceleration's rate is the jerk; the
#: load cell's reaction holds the accelerations too). The core's observation
#: table says which (its rate column, beamid_observations).
NO_RATE_KINDS = tuple(k.name for k in observations.kinds().values() if not k.rate)
#: null (perfect chain) value by kind
NULLS = {"time_offset": 0.0, "bias": 0.0, "scale": 1.0, "initial_velocity": 0.0}
_KIND_CODE = {1: "time_offset", 2: "bias", 3: "scale", 4: "initial_velocity"}


@dataclass(frozen=True)
class ChainSpec:
    """The nuisance parameters of a fit: ``t0`` {experiment: start},
    ``bias`` and ``scale`` {(experiment, quantity): start}, ``v0``
    {release: start} (its initial tip normal velocity, m/s)."""

    t0: dict[str, float] = field(default_factory=dict)
    bias: dict[tuple[str, str], float] = field(default_factory=dict)
    scale: dict[tuple[str, str], float] = field(default_factory=dict)
    v0: dict[str, float] = field(default_factory=dict)

    def __bool__(self) -> bool:
        return bool(self.t0 or self.bias or self.scale or self.v0)

    def order(self, experiments: list[str]) -> list[tuple[str, str, str]]:
        """(kind, experiment, observation) in the parameter order of the
        Fortran core (chain_layout): per experiment its t0, its v0, its
        biases, its scales, each in the order of the observation list
        (beamid.observations.ordered)."""
        out = []
        for e in experiments:
            if e in self.t0:
                out.append(("time_offset", e, ""))
            if e in self.v0:
                out.append(("initial_velocity", e, ""))
            for kind, table in (("bias", self.bias), ("scale", self.scale)):
                qs = [q for x, q in table if x == e]
                for q in sorted(qs, key=observations.sort_key):
                    out.append((kind, e, q))
        return out

    def names(self, experiments: list[str] | None = None) -> tuple[str, ...]:
        exps = experiments if experiments is not None else list(dict.fromkeys(
            list(self.t0) + list(self.v0) + [e for e, _ in self.bias]
            + [e for e, _ in self.scale]))
        return tuple(param_name(k, e, q) for k, e, q in self.order(exps))

    def starts(self, experiments: list[str]) -> np.ndarray:
        table = {"time_offset": self.t0, "bias": self.bias, "scale": self.scale,
                 "initial_velocity": self.v0}
        return np.array([table[k][e] if k in _PER_EXPERIMENT else table[k][(e, q)]
                         for k, e, q in self.order(experiments)], float)

    def encode(self, experiments: list[str], specs: Sequence[dict[str, float]] | np.ndarray,
               index: Mapping[str, int] | None = None) -> None:
        """Set the keys t0, v0, bias and scale (the core's key names) of
        each experiment's spec in ``specs`` (one dict per experiment, in the
        order of ``experiments``; a matrix of the legacy positional form,
        NEXPVAL x nexp, is set alike); ``index``: the problem's observation
        list, name -> 1-based entry (None: the kind codes)."""
        for j, e in enumerate(experiments):
            _set_keys(specs, j, {
                "t0": 1.0 if e in self.t0 else 0.0,
                "v0": 1.0 if e in self.v0 else 0.0,
                "bias": _mask([q for (x, q) in self.bias if x == e], index, "nuisance"),
                "scale": _mask([q for (x, q) in self.scale if x == e], index, "nuisance")})

    def with_values(self, experiments: list[str], values: np.ndarray) -> "ChainSpec":
        """The same parameters started at ``values`` (in :meth:`order`)."""
        t0, bias, scale, v0 = {}, {}, {}, {}
        for (k, e, q), v in zip(self.order(experiments), values):
            if k == "time_offset":
                t0[e] = float(v)
            elif k == "initial_velocity":
                v0[e] = float(v)
            else:
                (bias if k == "bias" else scale)[(e, q)] = float(v)
        return ChainSpec(t0, bias, scale, v0)

    def merged(self, other: "ChainSpec") -> "ChainSpec":
        """This spec with ``other``'s parameters added (its own values kept)."""
        return ChainSpec({**other.t0, **self.t0}, {**other.bias, **self.bias},
                         {**other.scale, **self.scale}, {**other.v0, **self.v0})


#: the nuisance kinds with one parameter per experiment (no channel)
_PER_EXPERIMENT = ("time_offset", "initial_velocity")


#: the losses of :func:`beamid.fit` and their Fortran codes (beamid_chain_fit)
LOSSES = {"linear": 0, "huber": 1, "cauchy": 2}


@dataclass(frozen=True)
class RowTreatment:
    """How the fit treats the rows: ``loss`` (linear, huber, cauchy), the
    ``burn_in`` time of each release (rows before it predicted, not
    fitted) and the channels whose sigma is estimated from the residuals."""

    loss: str = "linear"
    burn_in: dict[str, float] = field(default_factory=dict)
    estimate: tuple[tuple[str, str], ...] = ()

    def __bool__(self) -> bool:
        return self.loss != "linear" or bool(self.burn_in) or bool(self.estimate)

    def encode(self, experiments: list[str], specs: Sequence[dict[str, float]] | np.ndarray,
               index: Mapping[str, int] | None = None) -> None:
        """Set the keys loss, burn_in and sigma_est of each experiment's
        spec in ``specs`` (``specs`` and ``index`` as :meth:`ChainSpec.encode`)."""
        for j, e in enumerate(experiments):
            _set_keys(specs, j, {
                "loss": float(LOSSES[self.loss]),
                "burn_in": float(self.burn_in.get(e, 0.0)),
                "sigma_est": _mask([q for (x, q) in self.estimate if x == e], index,
                                   "estimate_sigma")})


def _set_keys(specs: Sequence[dict[str, float]] | np.ndarray, j: int,
              named: Mapping[str, float]) -> None:
    """Set keys ``named`` (the core's key names) of experiment j's spec:
    specs[j] a dict, or column j of a matrix of the legacy positional form."""
    if isinstance(specs, np.ndarray):
        for key, v in named.items():
            specs[spec_row(key), j] = v
    else:
        specs[j].update(named)


def _mask(names: list[str], index: Mapping[str, int] | None, what: str) -> float:
    """The channel mask of observations ``names``: bit q - 1 for entry q of
    the observation list ``index`` (None: the kind codes)."""
    table = index if index is not None else _ce.QUANTITY_CODES
    mask = 0
    for q in names:
        if q not in table:
            raise InputError(f"{what}: channel {q!r} is not among the data's observations "
                             f"({', '.join(table)})")
        if table[q] > MAX_CHANNEL_BITS:
            raise InputError(f"{what}: channel {q!r} is entry {table[q]} of the data's "
                             f"{len(table)} observations, expected one of the first "
                             f"{MAX_CHANNEL_BITS} (beamid.observations.ordered)")
        mask |= 1 << (table[q] - 1)
    return float(mask)


def parse_rows(loss: Any, burn_in: Any, estimate_sigma: Any, experiments: Mapping[str, Any],
               data) -> RowTreatment:
    """Check the ``loss``, ``burn_in`` and ``estimate_sigma`` arguments of
    :func:`beamid.fit`."""
    if not isinstance(loss, str) or loss not in LOSSES:   # the words test_chain names
        _check.fail("loss", loss, f"one of {', '.join(LOSSES)}")
    exps = dict(experiments)
    rel = [e for e, x in exps.items() if timed(x)]
    burn: dict[str, float] = {}
    if burn_in is not None:
        table = burn_in if isinstance(burn_in, Mapping) else {e: burn_in for e in rel}
        if not isinstance(burn_in, Mapping) and not rel:
            raise InputError("burn_in: the experiments have no release (no record in time)")
        table = _check.mapping("burn_in", table)
        for e, t in table.items():
            if e not in exps:
                raise InputError(f"burn_in: no experiment {e!r} (experiments: "
                                 f"{', '.join(exps)})")
            if not timed(exps[e]):
                raise InputError(f"burn_in: experiment {e!r} is static; a burn-in needs a "
                                 "record in time (a beamid.Release)")
            burn[e] = _check.real(f"burn_in[{e!r}]", t, min=0.0,
                                  expected="a time >= 0 (s)")
    channels = sorted(_channels(data))
    if estimate_sigma is None or estimate_sigma is False:
        est: list[tuple[str, str]] = []
    elif estimate_sigma is True:
        est = channels
    else:
        if not isinstance(estimate_sigma, (str, tuple, list)):
            _check.fail("estimate_sigma", estimate_sigma, "True, False, None, a quantity "
                        "name, an (experiment, quantity) pair or a list of them")
        items = [estimate_sigma] if isinstance(estimate_sigma, (str, tuple)) else \
            list(estimate_sigma)
        est = []
        for item in items:
            if isinstance(item, str):
                found = [c for c in channels if c[1] == _name(item)]
                if not found:
                    raise InputError(f"estimate_sigma: no experiment measures {item!r}")
                est += found
            elif isinstance(item, tuple) and len(item) == 2 and \
                    (str(item[0]), _name(item[1])) in channels:
                est.append((str(item[0]), _name(item[1])))
            else:
                raise InputError(f"estimate_sigma: channel {item!r} does not exist (channels: "
                                 + ", ".join(f"({e!r}, {q!r})" for e, q in channels) + ")")
    return RowTreatment(loss, burn, tuple(dict.fromkeys(est)))


def check_sigma_given(data, rows: RowTreatment | None, what: str = "fit") -> None:
    """InputError when rows of ``data`` have no sigma (NaN: an empty sigma
    field, or None in Measurements.from_rows) and their channel's sigma is
    not estimated (``rows.estimate``), naming the channels and the first row."""
    if data is None or not hasattr(data, "sigma"):
        return
    sigma = np.asarray(data.sigma, float)
    if not np.isnan(sigma).any():
        return
    estimated = set(rows.estimate) if rows else set()
    missing = [i for i in np.flatnonzero(np.isnan(sigma))
               if (data.experiment[i], data.quantity[i]) not in estimated]
    if not missing:
        return
    channels = list(dict.fromkeys((data.experiment[i], data.quantity[i]) for i in missing))
    raise InputError(
        f"{what}: sigma missing: {len(missing)} rows have no sigma ({data._where(missing[0])}"
        f" first) and no estimation is asked for their channel"
        f"{'s' if len(channels) > 1 else ''} "
        + ", ".join(f"({e!r}, {q!r})" for e, q in channels[:6])
        + (" ..." if len(channels) > 6 else "")
        + "; expected a sigma > 0 on every row, or estimate_sigma=True (or naming those "
        "channels) so that the fit estimates it from the residuals")


def from_deck(experiments: list, data) -> tuple[ChainSpec | None, RowTreatment | None]:
    """The measurement chain a deck's &fit asks for (beamid_chain_deck): its
    nuisance parameters and rows' treatment decoded from the experiments'
    specs ``experiments`` ((name, kind, spec) as the reader gives them: a
    spec by the core's key names, or a value column of the legacy positional
    form), channel masks over the data's observations in the core's order
    (beamid.observations.ordered). (None, None) when it asks nothing."""
    labels = observations.ordered(data.quantity)
    t0, bias, scale, burn, est, v0 = {}, {}, {}, {}, [], {}
    loss = "linear"

    def bits(v: float) -> list[str]:
        m = int(round(v))
        return [q for i, q in enumerate(labels[:MAX_CHANNEL_BITS]) if m >> i & 1]

    codes = {c: n for n, c in LOSSES.items()}
    keys = ("t0", "bias", "scale", "loss", "burn_in", "sigma_est")
    for name, kind, values in experiments:
        spec = values if isinstance(values, Mapping) else spec_from_column(values)
        t, b, sc, lo, bu, se = (float(spec.get(k, 0.0)) for k in keys)
        if t == 1.0:
            t0[name] = 0.0
        v0_flag = float(spec.get("v0", 0.0))
        if v0_flag == 1.0:
            v0[name] = 0.0
        bias.update({(name, q): 0.0 for q in bits(b)})
        scale.update({(name, q): 1.0 for q in bits(sc)})
        if lo:
            loss = codes[int(round(lo))]
        if bu > 0.0:
            burn[name] = bu
        est += [(name, q) for q in bits(se)]
    spec, rows = ChainSpec(t0, bias, scale, v0), RowTreatment(loss, burn, tuple(est))
    return (spec or None), (rows or None)


def param_name(kind: str, experiment: str, quantity: str) -> str:
    """``t0[exp]``, ``v0[exp]``, ``bias[exp:quantity]``, ``scale[exp:quantity]``."""
    if kind == "time_offset":
        return f"t0[{experiment}]"
    if kind == "initial_velocity":
        return f"v0[{experiment}]"
    return f"{kind}[{experiment}:{quantity}]"


def _channels(data) -> set[tuple[str, str]]:
    return set(zip(data.experiment, data.quantity)) if data is not None else set()


def _name(q: Any) -> str:
    """The canonical name of observation ``q`` (``strain@1:0.050`` is
    ``strain@1:0.05``); ``q`` itself when it is none (the caller says so)."""
    if not isinstance(q, str):
        return q
    try:
        return _canonical(q)
    except InputError:
        return q


def _is_observation(q: Any) -> bool:
    if not isinstance(q, str):
        return False
    try:
        observations.parse(q)
    except InputError:
        return False
    return True


def _no_rate_rows(data, experiment: str) -> list[str]:
    """The observations of ``experiment``'s rows that have no rate in the
    core (NO_RATE_KINDS): a clock offset cannot be fitted on its record."""
    if data is None:
        return []
    return sorted({q for e, q in zip(data.experiment, data.quantity) if e == experiment
                   and observations.parse(q).kind in NO_RATE_KINDS})


def parse_nuisance(nuisance: Any, experiments: Mapping[str, Any], data) -> ChainSpec:
    """Check and normalize the ``nuisance`` argument of :func:`beamid.fit`.

    ``{"time_offset": [experiment, ...], "bias": [(experiment, quantity),
    ...], "scale": [...], "initial_velocity": [release, ...]}``; each list may be a dict giving the start value
    (``{"free": 0.01}``, ``{("free", "w_tip"): 1e-3}``); a bare quantity
    name in ``bias``/``scale`` means that quantity in every experiment that
    measures it.
    """
    if nuisance is None:
        return ChainSpec()
    if isinstance(nuisance, ChainSpec):
        return nuisance
    nuisance = _check.mapping("nuisance", nuisance)
    exps = dict(experiments)
    channels = _channels(data)
    out: dict[str, dict] = {"time_offset": {}, "bias": {}, "scale": {}, "initial_velocity": {}}
    for kind, items in nuisance.items():
        if kind not in NUISANCE_KINDS:
            raise InputError(f"nuisance: unknown kind {kind!r}, expected one of "
                             f"{', '.join(NUISANCE_KINDS)}")
        if isinstance(items, (str, tuple)):
            items = [items]
        if not isinstance(items, (Mapping, list)):
            _check.fail(f"nuisance[{kind!r}]", items, "a list of experiments or channels, or "
                        "a dict of them to their start values")
        pairs = list(items.items()) if isinstance(items, Mapping) else \
            [(it, NULLS[kind]) for it in items]
        for item, start in pairs:
            start = _check.real(f"nuisance[{kind!r}][{_check.show(item)}]", start,
                                above=0.0 if kind == "scale" else None,
                                expected="a finite number" + (" > 0" if kind == "scale"
                                                              else ""))
            if not isinstance(item, str if kind in _PER_EXPERIMENT else (str, tuple)):
                _check.fail(f"nuisance[{kind!r}]", item, "an experiment name" if kind in
                            _PER_EXPERIMENT else "an (experiment, quantity) pair or a "
                            "quantity name")
            if kind == "initial_velocity":
                if item not in exps:
                    raise InputError(f"nuisance['initial_velocity']: no experiment {item!r} "
                                     f"(experiments: {', '.join(exps)})")
                if not timed(exps[item]):
                    raise InputError(f"nuisance['initial_velocity']: experiment {item!r} is "
                                     "static; an initial velocity needs a release (a "
                                     "beamid.Release)")
                out[kind][item] = start
                continue
            if kind == "time_offset":
                if item not in exps:
                    raise InputError(f"nuisance['time_offset']: no experiment {item!r} "
                                     f"(experiments: {', '.join(exps)})")
                if not timed(exps[item]):
                    raise InputError(f"nuisance['time_offset']: experiment {item!r} is "
                                     "static; a time offset needs a record in time (a "
                                     "beamid.Release)")
                bad = _no_rate_rows(data, item)
                if bad:
                    raise InputError(f"nuisance['time_offset']: experiment {item!r} has rows "
                                     f"of {', '.join(bad)}, whose rate (the jerk) the fit "
                                     "does not compute yet; expected a time offset only on "
                                     "a record without acceleration rows")
                out[kind][item] = start
                continue
            if isinstance(item, str):
                if not _is_observation(item):
                    raise InputError(f"nuisance[{kind!r}]: {item!r} is neither a quantity "
                                     f"nor an (experiment, quantity) pair")
                item = _name(item)
                found = sorted(c for c in channels if c[1] == item)
                if data is not None and not found:
                    raise InputError(f"nuisance[{kind!r}]: no experiment measures {item!r}")
                for c in found:
                    out[kind][c] = start
                continue
            if not (isinstance(item, tuple) and len(item) == 2):
                raise InputError(f"nuisance[{kind!r}]: {item!r}, expected an (experiment, "
                                 "quantity) pair or a quantity name")
            e, q = str(item[0]), str(item[1])
            if e not in exps:
                raise InputError(f"nuisance[{kind!r}]: no experiment {e!r} (experiments: "
                                 f"{', '.join(exps)})")
            if not _is_observation(q):
                raise InputError(f"nuisance[{kind!r}]: {q!r} is not a quantity, expected one "
                                 f"of {', '.join(_ce.QUANTITY_NAMES.values())} (a station "
                                 "kind as kind@beam:s)")
            q = _name(q)
            if data is not None and (e, q) not in channels:
                have = sorted(q2 for e2, q2 in channels if e2 == e)
                raise InputError(f"nuisance[{kind!r}]: channel ({e!r}, {q!r}) does not exist: "
                                 f"experiment {e!r} has no rows of {q!r} (it measures "
                                 f"{', '.join(have) or 'nothing'})")
            out[kind][(e, q)] = start
    return ChainSpec(out["time_offset"], out["bias"], out["scale"], out["initial_velocity"])


def layout(prob: "_ce.Problem", names: list[str]) -> list[tuple[str, str, str]]:
    """(kind, experiment, observation) of the nuisance parameters of a
    problem, as the Fortran core orders them (api_chain_layout: one source)."""
    labels = prob.observation_names()
    n, kinds, exps, qs = _call(_ce._api.api_chain_layout, prob.exp_kind, *prob.specs(),
                               len(labels))
    return [(_KIND_CODE[int(k)], names[int(e) - 1], labels[int(q) - 1] if q > 0 else "")
            for k, e, q in zip(kinds[:n], exps[:n], qs[:n])]


# ------------------------------------------------- the chain among the candidates

#: the measurement chain's candidates of beamid.diagnose (time histories)
CHAIN_CANDIDATES = ("clock_offset", "channel_bias", "channel_scale", "initial_velocity")
_CANDIDATE_KIND = {"clock_offset": "time_offset", "channel_bias": "bias",
                   "channel_scale": "scale", "initial_velocity": "initial_velocity"}


#: the chain's candidate effects (name, description), in the order they are
#: tried; beamid.diagnosis registers them (cause "measurement chain", release
#: fits only) and beamid.dyn_diagnosis puts them among the release's
#: default candidates, before the mesh
CANDIDATE_EFFECTS = (
    ("clock_offset", "a clock offset t0 of a release's record (the logger's zero is not "
     "the release)"),
    ("channel_bias", "a bias b of a channel (experiment, quantity): a camera's origin, a "
     "gauge's zero drift"),
    ("channel_scale", "a scale s of a channel: a gauge factor, an accelerometer's "
     "sensitivity"),
    ("initial_velocity", "an initial velocity v0 of a release (the tip's normal velocity "
     "at t = 0: the chain was not released at rest)"),
    ("gross_errors", "a few rows far off (a lost marker, a spike): the refit with a Huber "
     "loss"),
    ("noise", "noise larger than stated: white residuals with chi2/dof above 1 (the refit "
     "estimates the sigmas)"),
)

#: chain candidates tried only when named in ``candidates`` (not among the
#: release's defaults): a release's initial velocity v0 trades off against
#: the static load and the damping of a short record, and the defaults keep
#: the diagnoses (and the decks' outputs) they had
OPT_IN_CANDIDATES = ("initial_velocity",)


@dataclass
class DiagnosisExtension:
    """The nuisance parameters of a diagnosis: the fit's own (free, at their
    estimates) and the chain candidates' (held at their null values), with
    the values, the free indices (1-based) the problem needs and the
    parameter names of the candidates' blocks."""

    spec: ChainSpec
    values: np.ndarray
    free: np.ndarray
    names: dict[str, float]

    def trim(self, raw: dict, npar: int) -> None:
        """Keep the model's part of the refit parameter vectors, and record
        the chain's values by name (for the candidates' null values)."""
        raw["refit_params"] = np.asarray(raw["refit_params"])[:npar]
        raw["mesh_params"] = np.asarray(raw["mesh_params"])[:npar]
        raw["chain_values"] = dict(self.names)


def diagnosis_extension(fit, effects: list, names: list, blocks: list) -> DiagnosisExtension:
    """Add the chain's candidates to a diagnosis of ``fit``: fills in the
    ``names`` and ``blocks`` of the effects whose cause is the measurement
    chain (in place), and returns the nuisance parameters of the problem."""
    return extension(fit.model, fit.experiments, fit.data, fit.chain, effects, names, blocks)


def extension(model, experiments, data, own: ChainSpec | None, effects: list, names: list,
              blocks: list) -> DiagnosisExtension:
    """:func:`diagnosis_extension` of a problem (model, experiments, data)
    whose fit has the chain ``own`` (None: none); the ladder of
    :func:`beamid.improve` starts from it too."""
    exps = list(experiments)
    wanted = {_CANDIDATE_KIND[e.name] for e in effects if e.name in _CANDIDATE_KIND}
    own, cand = _candidates(experiments, data, own, wanted)
    spec = own.merged(cand)
    order = spec.order(exps)
    npar = model.vector().size
    index = {param_name(k, e, q): npar + 1 + i for i, (k, e, q) in enumerate(order)}
    values = spec.starts(exps)
    for c, eff in enumerate(effects):
        kind = _CANDIDATE_KIND.get(eff.name)
        if kind is None:
            continue
        table = {"time_offset": cand.t0, "bias": cand.bias, "scale": cand.scale,
                 "initial_velocity": cand.v0}[kind]
        ns = tuple(param_name(k, e, q) for k, e, q in order
                   if k == kind and ((e in table) if kind in _PER_EXPERIMENT
                                     else ((e, q) in table)))
        names[c] = ns
        blocks[c] = np.array([index[n] for n in ns], np.int32)
    free = np.array([index[n] for n in own.names(exps)], np.int32)
    return DiagnosisExtension(spec, values, free,
                              {param_name(k, e, q): float(v) for (k, e, q), v in
                               zip(order, values)})


def candidate_spec(fit, kinds: set[str]) -> tuple[ChainSpec, ChainSpec]:
    """(the fit's own chain, the candidates' parameters of ``kinds`` at their
    null values): a clock offset per release, a bias and a scale per release
    channel, those the fit has already left out."""
    return _candidates(fit.experiments, fit.data, fit.chain, kinds)


def _candidates(experiments, data, own: ChainSpec | None,
                kinds: set[str]) -> tuple[ChainSpec, ChainSpec]:
    exps = list(experiments)
    own = own or ChainSpec()
    if not kinds:
        return own, ChainSpec()
    if not hasattr(data, "experiment"):
        raise InputError(f"data = {type(data).__name__}, expected beamid.Measurements "
                         "(beamid.read_measurements)")
    rel = [e for e, x in experiments.items() if timed(x)]
    channels = sorted({(e, q) for e, q in zip(data.experiment, data.quantity)
                       if e in rel}, key=lambda c: (exps.index(c[0]),
                                                    observations.sort_key(c[1])))
    # a record with rows whose rate the core lacks takes no clock offset
    cand = ChainSpec(
        {e: 0.0 for e in rel if e not in own.t0 and not _no_rate_rows(data, e)}
        if "time_offset" in kinds else {},
        {c: 0.0 for c in channels if c not in own.bias} if "bias" in kinds else {},
        {c: 1.0 for c in channels if c not in own.scale} if "scale" in kinds else {},
        {e: 0.0 for e in rel if e not in own.v0} if "initial_velocity" in kinds else {})
    return own, cand


def split_ladder_fit(raw: dict, free0, npar: int, spec: ChainSpec,
                     exps: list[str]) -> tuple[dict, list[int], ChainSpec]:
    """A ladder rung's fit (free parameters in the ladder's order, the
    parameter vector with every chain parameter) as beamid.estimation's
    ``_result`` takes it: (the dict with the model's free parameters first,
    then the chain's free ones, and the vector cut to the model's and those;
    the model's free indices, 0-based; the free chain parameters at their
    estimates)."""
    free0 = [int(i) for i in free0]
    phys = [i for i in free0 if i < npar]
    chain = sorted(i for i in free0 if i >= npar)
    perm = np.array([free0.index(i) for i in phys + chain], int)
    params = np.asarray(raw["params"], float)
    order = spec.order(exps)
    sub = ChainSpec()
    for i in chain:
        k, e, q = order[i - npar]
        if k == "time_offset":
            sub.t0[e] = float(params[i])
        elif k == "initial_velocity":
            sub.v0[e] = float(params[i])
        else:
            (sub.bias if k == "bias" else sub.scale)[(e, q)] = float(params[i])
    out = dict(raw, params=np.concatenate([params[:npar], params[chain]]))
    if perm.size:
        out.update(sigmas=np.asarray(raw["sigmas"])[perm],
                   cov=np.asarray(raw["cov"])[np.ix_(perm, perm)],
                   corr=np.asarray(raw["corr"])[np.ix_(perm, perm)],
                   flags=np.asarray(raw["flags"])[perm],
                   log_params=np.asarray(raw["log_params"])[perm])
    return out, phys, sub


# ------------------------------------- gross errors and noise among the candidates

#: the row candidates of the measurement chain (beamid.diagnose, after the
#: parameter candidates' score tests and refits)
ROW_CANDIDATES = ("gross_errors", "noise")
#: at most this share of the rows (and at least 3) may be gross errors: more
#: outlying rows are a misfit, not lost markers
GROSS_SHARE = 0.02


def judged_fit(fit):
    """The fit restricted to the rows it judges (fitted, not gross errors),
    as a plain fit on those rows: what the score tests and refits of a
    diagnosis see. The fit itself when it judges every row."""
    keep = np.ones(len(fit.residuals), bool)
    if fit.fitted_rows is not None:
        keep &= np.asarray(fit.fitted_rows, bool)
    keep[list(fit.gross_errors)] = False
    if keep.all() and not np.isnan(np.asarray(fit.data.sigma, float)).any():
        return fit    # (rows without sigma take the fit's estimate below)
    idx = np.flatnonzero(keep)
    data = fit.data.__class__.from_rows(
        [(fit.data.experiment[i], float(fit.data.t[i]), fit.data.quantity[i],
          float(fit.data.value[i]), float(fit.residuals[i].sigma)) for i in idx],
        source=fit.data.source)
    return dataclasses.replace(fit, data=data, residuals=[fit.residuals[i] for i in idx],
                               loss="linear", weights=None, fitted_rows=None,
                               gross_errors=(), sigma_estimates={})


def gross_rows(fit, alpha: float) -> np.ndarray:
    """Rows of ``fit`` that are gross errors: beyond the Bonferroni level
    ``alpha`` / n of the largest of n normal residuals, judged on the scale
    of the bulk (1.4826 times the median absolute deviation of the
    normalized residuals, at least 1, so a misfit of the physics does not
    make its larger residuals outliers); none when more than GROSS_SHARE of
    the rows (at least 3) would be."""
    z = np.array([r.normalized for r in fit.residuals])
    n = z.size
    if n < 5:
        return np.zeros(0, int)
    scale = max(1.0, 1.4826 * float(np.median(np.abs(z - np.median(z)))))
    p_row = _ce.chi2_sf_many((z / scale) ** 2, np.ones(n, np.int32))
    rows = np.flatnonzero(p_row < alpha / n)
    return rows if rows.size <= max(3, int(GROSS_SHARE * n)) else np.zeros(0, int)
