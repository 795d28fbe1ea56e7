"""Helpers for tests and benchmarks of the node: isolated ROS domains, polling with timeouts."""
import contextlib
import os
import time

import rclpy
from rclpy.executors import SingleThreadedExecutor

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FASTDDS_PROFILE = os.path.join(ROOT, "config", "fastdds_profile.xml")
PARAMS_FILE = os.path.join(ROOT, "config", "contact_sim.params.yaml")


def ros_env(domain_id, base=None):
    """Environment for a child ROS process (or this one) on its own domain, localhost only,
    with the fast-discovery Fast DDS profile."""
    env = dict(os.environ if base is None else base)
    env.update(ROS_DOMAIN_ID=str(domain_id), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
               FASTRTPS_DEFAULT_PROFILES_FILE=FASTDDS_PROFILE, PYTHONUNBUFFERED="1")
    env.pop("ROS_LOCALHOST_ONLY", None)
    return env


@contextlib.contextmanager
def ros_context(domain_id):
    """A fresh ``rclpy.Context`` on ``domain_id`` (shut down on exit)."""
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=domain_id)
    try:
        yield ctx
    finally:
        ctx.try_shutdown()


class WaitTimeout(AssertionError):
    """A condition did not come true in time. Not an ``OSError`` (as ``TimeoutError`` is), which
    ``domain_coordinator.domain_id()`` would swallow and turn into a confusing RuntimeError."""


class Spinner:
    """A single-threaded executor on one context, with ``until(predicate, timeout)``."""

    def __init__(self, ctx, *nodes):
        self.executor = SingleThreadedExecutor(context=ctx)
        for n in nodes:
            self.executor.add_node(n)

    def add(self, node):
        self.executor.add_node(node)

    def until(self, predicate, timeout=10.0, what="condition"):
        deadline = time.monotonic() + timeout
        while not predicate():
            if time.monotonic() > deadline:
                raise WaitTimeout(f"timed out after {timeout} s waiting for {what}")
            self.executor.spin_once(timeout_sec=0.02)
        return True

    def call(self, client, request, timeout=10.0):
        if not client.wait_for_service(timeout_sec=0.0):
            self.until(lambda: client.service_is_ready(), timeout, f"service {client.srv_name}")
        future = client.call_async(request)
        self.until(future.done, timeout, f"response of {client.srv_name}")
        return future.result()

    def shutdown(self):
        self.executor.shutdown(timeout_sec=1.0)
