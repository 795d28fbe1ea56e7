"""The step pipeline: free motion, detection, time of impact, response.

Until detection and response land this only advances free motion; ``World.step`` calls
``step(world, dt)``.
"""
from .contacts import Contacts


def step(world, dt):
    """Advance ``world`` by ``dt`` (already validated, > 0)."""
    world._advance_free(dt)
    world.time += dt
    world.contacts = Contacts.empty()
