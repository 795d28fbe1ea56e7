"""Error types of the engine. Every refusal names the thing and the reason."""


class ContactSimError(ValueError):
    """Bad input to the engine: names what was wrong and why. World state is unchanged."""


class BoundsError(ContactSimError):
    """A finite value beyond a world bound (``settings.max_position``, ``max_speed``, ...): refused
    like any bad input, but a caller may count it apart (the node's ``out_of_bounds`` poses)."""


class SceneError(ContactSimError):
    """A scene failed validation; ``path`` is the dotted location in the scene (``bodies[3].mass``)."""

    def __init__(self, path, reason):
        self.path = path
        self.reason = reason
        super().__init__(f"{path}: {reason}" if path else reason)


class EngineError(ContactSimError, RuntimeError):
    """A step that failed on valid input (an exception inside the engine, or a non-finite
    result): an engine bug to report, not bad input. The world is as it was before the step.
    A ``ContactSimError`` too, so one ``except`` keeps a caller's world alive (the node's)."""


class StudyError(ContactSimError):
    """A study file failed validation; ``path`` is its location in the study
    (``study.grid['settings.dt'][2]``), ``reason`` what is wrong with it."""

    def __init__(self, path, reason):
        self.path = path
        self.reason = reason
        super().__init__(f"{path}: {reason}" if path else reason)
