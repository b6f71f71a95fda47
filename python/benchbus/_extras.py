"""What a missing optional extra says, in one place: the simulators' package, the command
line and the pytest plugin give one message, the lab-framework integrations another."""

from __future__ import annotations

__all__ = ["SIM_MODULES", "need_framework", "sim_missing"]

#: The top-level modules the ``sim`` extra installs (pymodbus, pyserial).
SIM_MODULES = ("pymodbus", "serial")


def sim_missing(exc: ImportError) -> ModuleNotFoundError | None:
    """The error to raise for ``exc`` if it is a module of the ``sim`` extra missing (or one
    too old or new to have what the simulators import), else None.

    Its message says what to install: ``pip install 'benchbus[sim]'``.
    """
    name = exc.name or ""
    if name.split(".")[0] not in SIM_MODULES:
        return None
    return ModuleNotFoundError(
        f"the simulators need pymodbus and pyserial: pip install 'benchbus[sim]' ({exc})",
        name=name,
    )


def need_framework(
    module: str, needs: str, extra: str, package: str, missing: ImportError | None
) -> None:
    """Raise the ImportError ``module`` (``benchbus.qcodes``, ``benchbus.ophyd``) raises when
    used without the framework it wraps (``needs``: the import ``package``, installed by
    the extra ``extra``), if that failed to import with ``missing`` (None: it is there).
    Its message says what to install."""
    if missing is not None:
        raise ImportError(
            f"{module} needs {needs} (Python 3.11 or later): pip install 'benchbus[{extra}]' "
            f"({missing})",
            name=package,
        ) from missing
