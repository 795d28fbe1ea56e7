"""Entry point of ``contact_sim_node``: SIGINT and SIGTERM caught from the first moment.

This module imports nothing heavy: the signal handlers are in place before rclpy, numpy and the
engine are imported (about half a second), so a signal at any time during start-up ends the node
cleanly with status 0 instead of killing it (SIGTERM's default) or raising in the middle of
rclpy's set-up. rclpy's own handlers are not installed: they shut the context down under a running
callback ("publisher's context is invalid") or under the node's construction ("rcl node's context
is invalid").
"""
import signal
import sys
import threading


class StopSignals:
    """SIGINT and SIGTERM set ``requested``, which the spin loop checks. A second signal acts as
    usual (SIGINT raises KeyboardInterrupt, SIGTERM kills): a way out of a stuck shutdown."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self):
        self.requested = False
        self._old = {}
        self.installed = threading.current_thread() is threading.main_thread()
        if self.installed:
            for s in self.SIGNALS:
                self._old[s] = signal.signal(s, self._on_signal)

    def _on_signal(self, signum, frame):
        self.requested = True
        for s in self.SIGNALS:
            signal.signal(s, signal.SIG_DFL if s == signal.SIGTERM else signal.default_int_handler)

    def restore(self):
        for s, old in self._old.items():
            signal.signal(s, old)


def main(args=None):
    """Console script ``contact_sim_node``: 0 on SIGINT/SIGTERM (also during start-up), 2 when the
    configuration is bad."""
    stop = StopSignals()
    node = None
    rclpy = None
    try:
        import rclpy
        from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        import contact_sim

        from .node import ConfigError, ContactSimNode

        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO if stop.installed else None)
        if stop.requested:
            return 0
        try:
            node = ContactSimNode()
        except (ConfigError, contact_sim.ContactSimError) as exc:
            print(f"contact_sim_node: cannot start: {exc}", file=sys.stderr, flush=True)
            return 2
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        node.freeze_heap()
        node.set_thread_priority()   # this thread spins: the ticks run in it
        try:
            while not stop.requested and rclpy.ok():
                executor.spin_once(timeout_sec=0.1)   # a signal is seen within 0.1 s
        except (KeyboardInterrupt, ExternalShutdownException):
            pass
        finally:
            try:
                node.close_outputs()
            except Exception as exc:  # the context went away first (an external shutdown): nothing to clear
                print(f"contact_sim_node: markers not cleared: {exc}", file=sys.stderr, flush=True)
            executor.shutdown(timeout_sec=1.0)
    except KeyboardInterrupt:   # a second SIGINT during start-up or shutdown
        pass
    finally:
        if node is not None:
            node.destroy_node()
        if rclpy is not None:
            rclpy.try_shutdown()
        stop.restore()
    return 0


if __name__ == "__main__":
    sys.exit(main())
