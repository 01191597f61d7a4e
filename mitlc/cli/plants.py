"""``mitlc plants``: every plant a spec can name, with its state, parameters and defaults."""

from __future__ import annotations

import click

from mitlc.cli.common import handle_errors, plant_file_option

__all__ = ["plants"]


@click.command("plants")
@plant_file_option
@handle_errors
def plants() -> None:
    """List the plants a spec's 'plant NAME' line can name.

    mitlc's own, those of installed packages (entry point group 'mitlc.plants') and those of
    --plant-file; for each its state variables with
    their bounds (angles wrap), its inputs with their boxes (none listed: one input u in
    [-u_max, u_max]), its parameters with their defaults and its default spec. Any
    registered Gymnasium environment is a plant too: 'plant gym:ID' with 'state' lines mapping its
    observation; --gym-module MODULE registers those of a module of yours (mitlc docs plants)."""
    from mitlc.plants.base import PLANTS
    from mitlc.plants.user import discover

    for problem in discover():
        click.echo(f"warning: {problem}", err=True)
    for name in sorted(PLANTS):
        p = PLANTS[name]
        click.echo(f"{name}: {p.description}" if p.description else name)
        for v in p.state:
            kind = ", angle (wrapped to [-pi, pi))" if v.periodic else ""
            click.echo(f"  state  {v.name} in [{v.lo:g}, {v.hi:g}]{kind}")
        for u in p.inputs or ():  # none declared: one input u in [-u_max, u_max], u_max a parameter
            click.echo(f"  input  {u.name} in [{u.lo:g}, {u.hi:g}]")
        click.echo("  params " + ", ".join(f"{k} = {val:g}" for k, val in p.defaults.items()))
        if p.default_spec:
            click.echo(f"  default spec: {p.default_spec.removesuffix('.mitl')}")
    click.echo(
        "gym:ID: any registered Gymnasium environment with continuous actions (a Box), e.g. gym:Pendulum-v1 "
        "(--gym-module MODULE registers a module's own); "
        "a spec maps its state variables to the observation, 'state q = atan2(obs[1], obs[0]), w = obs[2]' "
        "(shipped: gym/mountain_car_reach, gym/pendulum_v1_swing_up)"
    )
