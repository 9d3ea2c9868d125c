"""All three decisions of one environment by their rule codes: what ``Policy.act`` and the rollouts call.

Part of :mod:`wfbench.policies.kernels`; the branch of :func:`act_rules` for a rule is
where a new rule's code meets its kernel (``docs/design.md``, "Adding things").
:func:`act_codes` is what compiled code calls: given the codes as integer literals it
compiles only their rules (the compiled episode, ``Policy.act`` and the lookaheads' futures:
one compilation per code triple), given them at run time every rule (the oracle's
roll-forward, which plays many composites in one compiled batch).
"""

from __future__ import annotations

from numba import njit, types
from numba.extending import overload
from wfbench.policies.kernels.common import (
    D_ASSIGN,
    D_ASSIGN_SPARSE,
    D_INVERSE,
    D_NEAREST,
    D_RANDOM,
    HP_EPS,
    HP_NOISE,
    P_FACILITY,
    P_FACILITY_SPARSE,
    P_GAUSSIAN,
    P_RANDOM,
    P_SPATIAL,
    W_EPSILON,
    W_RANDOM,
    W_STAFFING,
    W_THRESHOLD,
)
from wfbench.policies.kernels.dispatch import (
    dispatch_assignment,
    dispatch_assignment_sparse,
    dispatch_inverse_distance,
    dispatch_nearest,
    dispatch_random,
)
from wfbench.policies.kernels.positioning import (
    observe_history,
    positioning_facility,
    positioning_facility_sparse,
    positioning_random,
    positioning_spatial,
)
from wfbench.policies.kernels.workforce import workforce_random, workforce_staffing, workforce_threshold

from wfbench.core.entrypoints import bind


@njit(cache=True, inline="always")
def act_rules(dc, wc, pc, b, O, S, hp, dispatch, workforce, positioning, t, lazy):
    """Fill the three decisions of environment b for the dispatch, workforce and positioning rule codes.

    ``hp`` has a row per decision. ``lazy`` (the compiled episode and the roll-forward, where
    all three decisions are built in) skips the spatial positioning weights on steps whose
    workforce action is the no-op: the step does not read them then, and the demand history
    they come from is still updated, so the episode is the same. ``Policy.act`` always fills
    them (another agent may hire).

    Inlined into its caller: where the codes are constants there (:func:`act_codes`), numba
    prunes the other rules' branches before typing them, so their kernels are not compiled.
    Callers compile this without numba's runtime (see ``wfbench.core.dynamics.step_env``): the
    heuristic and random kernels work in the scratch arrays of the policy state, and the
    solver kernels, which allocate, are compiled with ``_nrt=True`` set explicitly.
    """
    if dc == D_NEAREST:
        dispatch_nearest(b, O, dispatch[b], S.req_buf[b], S.per_buf[b])
    elif dc == D_INVERSE:
        dispatch_inverse_distance(b, O, dispatch[b], S.keys[b, 0], t, S.used_buf[b], S.w_buf[b])
    elif dc == D_RANDOM:
        dispatch_random(b, O, dispatch[b], S.keys[b, 0], t, S.used_buf[b])
    elif dc == D_ASSIGN:
        dispatch_assignment(b, O, dispatch[b], hp[0])
    elif dc == D_ASSIGN_SPARSE:
        dispatch_assignment_sparse(b, O, dispatch[b], hp[0])
    else:
        dispatch[b, :] = O.personnel.shape[1]
    hw = hp[1]
    if wc == W_THRESHOLD:
        workforce[b] = workforce_threshold(b, O, S, hw, S.keys[b, 1], t, 0.0)
    elif wc == W_EPSILON:
        workforce[b] = workforce_threshold(b, O, S, hw, S.keys[b, 1], t, hw[HP_EPS])
    elif wc == W_RANDOM:
        workforce[b] = workforce_random(b, O, S.keys[b, 1], t)
    elif wc == W_STAFFING:
        workforce[b] = workforce_staffing(b, O, S, hw, S.keys[b, 1], t)
    else:
        workforce[b] = 0
    hpp = hp[2]
    if pc == P_SPATIAL or pc == P_GAUSSIAN:
        if lazy and workforce[b] == 0:
            observe_history(b, O, S, hpp)
        else:
            noise = hpp[HP_NOISE] if pc == P_GAUSSIAN else 0.0
            positioning_spatial(b, O, S, hpp, positioning[b], S.keys[b, 2], t, noise)
    elif pc == P_RANDOM:
        positioning_random(b, O, positioning[b], S.keys[b, 2], t)
    elif pc == P_FACILITY:
        positioning_facility(b, O, S, hpp, positioning[b], t)
    elif pc == P_FACILITY_SPARSE:
        positioning_facility_sparse(b, O, S, hpp, positioning[b], t)
    else:
        positioning[b, :, :] = 0.0


def act_codes(dc, wc, pc, b, O, S, hp, dispatch, workforce, positioning, t, lazy):
    """:func:`act_rules` as compiled code calls it: with literal codes only their rules are compiled.

    Called from compiled code. Where ``dc``, ``wc`` and ``pc`` are typed as integer literals
    (the entry point bound with ``bind(..., literal=...)``), it is :func:`act_rules` with the
    codes as constants, so numba prunes every other rule before typing it: an episode of the
    heuristic does not compile the assignment, the p-median or the LAP (docs/performance.md,
    "Cold compile"). Where they are plain integers, it is :func:`act_rules` with every rule.
    """
    raise NotImplementedError("act_codes is called from compiled code only")


# prefer_literal: numba tries an overload with the arguments' plain types first, which would take the every-rule
# implementation for literal codes too
@overload(act_codes, jit_options={"_nrt": False}, prefer_literal=True)
def _act_codes(dc, wc, pc, b, O, S, hp, dispatch, workforce, positioning, t, lazy):
    if all(isinstance(c, types.IntegerLiteral) for c in (dc, wc, pc)):
        d, w, p = dc.literal_value, wc.literal_value, pc.literal_value

        def constant(dc, wc, pc, b, O, S, hp, dispatch, workforce, positioning, t, lazy):
            act_rules(d, w, p, b, O, S, hp, dispatch, workforce, positioning, t, lazy)

        return constant
    if all(isinstance(c, types.Integer) for c in (dc, wc, pc)):

        def run_time(dc, wc, pc, b, O, S, hp, dispatch, workforce, positioning, t, lazy):
            act_rules(dc, wc, pc, b, O, S, hp, dispatch, workforce, positioning, t, lazy)

        return run_time
    return None


@njit(cache=True, _nrt=False, nogil=True)  # see act_rules; nogil and lazy as the roll-forward's (one compilation)
def act_range(dc, wc, pc, O, S, hp, dispatch, workforce, positioning, t, lazy):
    """Every environment's three decisions (``Policy.act``): :func:`act_codes` per environment.

    ``lazy`` is False (:func:`act_batch`). It is an argument, and the flags are the
    roll-forward's, so that a lookahead compiles its base's rules once for both
    (``wfbench.policies.kernels.forward.roll_range``).
    """
    for b in range(O.facilities.shape[0]):
        act_codes(dc, wc, pc, b, O, S, hp, dispatch, workforce, positioning, t[b], lazy)


def act_batch(O, S, codes, hp, dispatch, workforce, positioning, t) -> None:
    """Fill every environment's decisions with the rules ``codes`` (int64 (3,)), compiled for those rules only.

    ``O`` is the observation in the kernels' tuple (``as_obs``), ``S`` the kernels' policy
    state; ``dispatch``, ``workforce`` and ``positioning`` are filled in place. The entry point
    is bound once per code triple and argument types (:func:`wfbench.core.entrypoints.bind`).
    """
    args = (int(codes[0]), int(codes[1]), int(codes[2]), O, S, hp, dispatch, workforce, positioning, t, False)
    bind(act_range, *args, literal=(0, 1, 2))(*args)
