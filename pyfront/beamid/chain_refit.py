"""The measurement chain's refits (beamid.chain holds its parameters and rows;
beamid.estimation imports that module, so the refits, which call
beamid.fit, live here): add_effect's refit with a chain candidate, the fit
without its gross errors, and diagnose's row candidates (gross errors,
noise)."""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from . import _core_estimation as _ce
from .chain import (_CANDIDATE_KIND, ChainSpec, RowTreatment, _channels, candidate_spec,
                    gross_rows)
from .errors import InputError
from .estimation import fit as _fit


def add_chain_effect(fit, name: str, *, max_iter: int = 50):
    """:func:`beamid.add_effect` for a measurement-chain candidate: the fit
    again with the candidate's nuisance parameters (every release's clock
    offset, every release channel's bias or scale) fitted too, with a Huber
    loss (``gross_errors``), or with the sigmas estimated (``noise``); what
    the fit already had is kept."""
    rows = fit.treatment or RowTreatment()
    own = fit.chain or ChainSpec()
    if name == "gross_errors":
        found = gross_rows(fit, 0.01)
        if not found.size:
            raise InputError("effect 'gross_errors': no row of this fit is a gross error "
                             "(beyond the Bonferroni level 0.01 / n on the bulk's scale)")
        return without_rows(fit, found)
    elif name == "noise":
        channels = tuple(sorted(_channels(fit.data)))
        if set(channels) <= set(rows.estimate):
            raise InputError("effect 'noise': the fit estimates every sigma already")
        rows = dataclasses.replace(rows, estimate=channels)
        spec = own
    else:
        own, cand = candidate_spec(fit, {_CANDIDATE_KIND[name]})
        if not cand:
            raise InputError(f"effect {name!r}: no parameter left to add (the fit has every "
                             f"{_CANDIDATE_KIND[name].replace('_', ' ')} already, or no "
                             "release)")
        spec = own.merged(cand)
    out = _fit(fit.model, fit.experiments, fit.data, free=fit.free, prior=fit.prior or None,
               max_iter=max_iter, nuisance=spec, loss=rows.loss, burn_in=rows.burn_in or None,
               estimate_sigma=list(rows.estimate) or None, starts=0, mesh=False)
    return dataclasses.replace(out, nominal=fit.nominal)


def without_rows(fit, rows):
    """The fit again without ``rows`` (gross errors): a plain fit of the
    other rows, from the fit's estimates, with its chain; its note names the
    rows left out (by their number in ``fit.data``)."""
    drop = set(int(i) for i in rows)
    idx = [i for i in range(len(fit.data)) if i not in drop]
    data = fit.data.__class__.from_rows(
        [(fit.data.experiment[i], float(fit.data.t[i]), fit.data.quantity[i],
          float(fit.data.value[i]), float(fit.residuals[i].sigma)) for i in idx],
        source=fit.data.source)
    rows_t = fit.treatment or RowTreatment()
    out = _fit(fit.model, fit.experiments, data, free=fit.free, prior=fit.prior or None,
               nuisance=fit.chain, burn_in=rows_t.burn_in or None, starts=0, mesh=False)
    gone = ", ".join(f"{i} ({fit.data.experiment[i]} {fit.data.quantity[i]} t = "
                     f"{float(fit.data.t[i]):g})" for i in sorted(drop))
    return dataclasses.replace(out, nominal=fit.nominal,
                               note=(out.note + "; " if out.note else "")
                               + f"gross errors left out: rows {gone}")


def row_candidates(fit, effects, alpha_each: float, cls):
    """The gross-error and noise candidates asked for in ``effects`` of the
    (judged) fit ``fit``: a list of ``cls`` (beamid.Candidate) objects."""
    names = {e.name for e in effects}
    out = []
    z = np.array([r.normalized for r in fit.residuals])
    n = z.size
    if "gross_errors" in names and n > 0:
        rows = gross_rows(fit, alpha_each)
        if rows.size:
            refit = without_rows(fit, rows)
            drop = float(fit.chi2 - refit.chi2)
            p = _ce.chi2_sf(max(drop, 0.0), int(rows.size))
            params = tuple(f"row {i}" for i in rows)
            off = {f"row {i}": float(fit.residuals[i].measured - fit.residuals[i].model)
                   for i in rows}
            sig = {f"row {i}": float(fit.residuals[i].sigma) for i in rows}
            significant = p < alpha_each
            out.append(cls("gross_errors", params, "tested",
                           score_drop=float(np.sum(z[rows] ** 2)),
                           score_p=_ce.chi2_sf(float(np.sum(z[rows] ** 2)), int(rows.size)),
                           first_order=off, first_order_sigma=sig, refit=True,
                           refit_tried=True, lr_drop=drop, lr_p=p, refit_estimate=off,
                           refit_sigma=sig, refit_model=refit.model,
                           significant=significant, acceptable=significant,
                           cause="measurement chain"))
        else:
            out.append(cls("gross_errors", (), "tested", score_drop=0.0, score_p=1.0,
                           cause="measurement chain"))
    if "noise" in names and fit.dof > 0:
        chi2 = fit.chi2 + fit.chi2_prior
        p = _ce.chi2_sf(chi2, fit.dof)
        factor = math.sqrt(chi2 / fit.dof)
        est = {"sigma factor": factor}
        sd = {"sigma factor": factor / math.sqrt(2.0 * fit.dof)}
        out.append(cls("noise", ("sigma factor",), "tested", score_drop=float(chi2 - fit.dof),
                       score_p=p, first_order=est, first_order_sigma=sd,
                       significant=p < alpha_each, acceptable=p < alpha_each,
                       cause="measurement chain"))
    return out
