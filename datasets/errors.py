"""The one error type for bad input, raised by every package and reported by the CLI.

A message names what is wrong and where: the file and line, the topic, the field, the
time. The CLI prints it as one line and exits with status 2, without a traceback.
"""


class InputError(ValueError):
    """Bad or unusable input: a malformed file, a missing topic, NaN samples, time going
    backwards, an unknown name, a sensor an estimator needs but a dataset lacks."""
