"""The one error type for bad input, raised by every package and reported by the CLI.

A message names what is wrong and where: the file and line, the topic, the field, the
time. The CLI prints it as one line and exits with status 2, without a traceback.
"""


class InputError(ValueError):
    """Bad or unusable input: a malformed file, a missing topic, NaN samples, time going
    backwards, an unknown name, a sensor an estimator needs but a dataset lacks."""


def one_line(error: BaseException) -> str:
    """``"Type: first line of the message"``: how a failed run or probe is reported in a
    table note or a progress line."""
    text = str(error).strip().splitlines()
    return f"{type(error).__name__}: {text[0] if text else ''}".rstrip(": ")


def did_you_mean(name: str, known: list[str] | tuple[str, ...]) -> str:
    """``" (did you mean 'x'?)"`` for the known name closest to ``name`` (difflib, cutoff
    0.6), or ``""`` when none is close: a hint for a misspelt name, key, topic or suite."""
    import difflib

    close = difflib.get_close_matches(str(name), [str(k) for k in known], n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ""
