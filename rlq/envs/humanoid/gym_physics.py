"""Gym's Humanoid-v1 physics on brax's humanoid model, one difference at a time (``env.contacts``,
``env.integrator``, ``env.solver_iterations``).

brax's humanoid.xml is Gym's with three physics changes: only the two feet's spheres touch the floor
(every other geom has ``contype=0 conaffinity=0``; in Gym's every geom collides with the floor and with
the others, frictionless between limbs: ``condim=1``, ``margin=0.001``), Euler integration instead of
RK4, and on MJX one Newton iteration (4 line-search steps) instead of Gym's 50 PGS iterations, which
MJX does not implement. Mania et al.'s augmented random search reached 6000 on Gym's physics; these
keys let a run ask for it, one change at a time, on an otherwise unchanged env (the same bodies, motors,
reward and observation). They rebuild the brax system from brax's humanoid.xml with the edits made in
MuJoCo's model spec, and keep brax's MJX solver settings unless ``solver_iterations`` says otherwise.
"""

from __future__ import annotations

from importlib import resources
from typing import Any

import mujoco
from brax.io import mjcf as brax_mjcf

from rlq.declared.envs.humanoid import Config

#: env.integrator's names as MuJoCo's integrators
MUJOCO_INTEGRATORS = {"euler": mujoco.mjtIntegrator.mjINT_EULER, "rk4": mujoco.mjtIntegrator.mjINT_RK4}
#: the model brax's humanoid loads (brax.envs.humanoid)
BRAX_HUMANOID_XML = resources.files("brax") / "envs" / "assets" / "humanoid.xml"
#: the floor geom, whose contact settings Gym and brax share
FLOOR = "floor"
#: Gym's humanoid.xml's default geom: every geom collides, frictionless between limbs (the floor's condim=3 wins
#: against it), a 1 mm margin
GYM_GEOM = {"contype": 1, "conaffinity": 1, "condim": 1, "margin": 0.001}


def is_brax_physics(contacts: str, integrator: str, solver_iterations: int | None) -> bool:
    """True when the keys hold their declared defaults, brax's own physics: nothing to rebuild."""
    return (contacts, integrator, solver_iterations) == (Config.contacts, Config.integrator, Config.solver_iterations)


def gym_model(contacts: str, integrator: str) -> mujoco.MjModel:
    """brax's humanoid.xml compiled with Gym's contacts (``contacts="all"``) and integrator as asked. Edited in
    MuJoCo's model spec, not in a compiled model, whose collision filter (per body) is derived when it compiles."""
    spec = mujoco.MjSpec.from_file(str(BRAX_HUMANOID_XML))
    if contacts == "all":
        for geom in spec.geoms:
            if geom.name != FLOOR:
                geom.contype = GYM_GEOM["contype"]
                geom.conaffinity = GYM_GEOM["conaffinity"]
                geom.condim = GYM_GEOM["condim"]
                geom.margin = GYM_GEOM["margin"]
    spec.option.integrator = MUJOCO_INTEGRATORS[integrator]
    return spec.compile()


def gym_system(sys: Any, contacts: str, integrator: str, solver_iterations: int | None) -> Any:
    """brax's humanoid system ``sys`` rebuilt on ``gym_model``'s model, with ``sys``'s MJX solver settings
    (solver, disabled flags, iterations, line-search steps) and ``solver_iterations`` in place of its
    iterations if given."""
    rebuilt = brax_mjcf.load_model(gym_model(contacts, integrator))
    iterations = sys.opt.iterations if solver_iterations is None else int(solver_iterations)
    return rebuilt.tree_replace(
        {
            "opt.solver": sys.opt.solver,
            "opt.disableflags": sys.opt.disableflags,
            "opt.iterations": iterations,
            "opt.ls_iterations": sys.opt.ls_iterations,
        }
    )
