"""Typed Hydra configs of lanelab's command-line tools: one error, one loader, shared checks.

Each tool keeps its defaults in ``conf/<tool>.yaml`` and its schema (which keys exist and
their types) in a dataclass; OmegaConf then rejects an unknown key or a wrong type by
name, and the tool's ``validate`` uses the checks below to reject values that cannot
work, naming the key, before anything is read or written.
"""

from __future__ import annotations

import dataclasses
import errno
import os
import sys
import tempfile
import typing
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Callable, Sequence, TypeVar

from hydra import compose, initialize_config_module
from hydra.core.config_store import ConfigStore
from hydra.errors import HydraException, MissingConfigException, OverrideParseException
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import ConfigKeyError, MissingMandatoryValue, OmegaConfBaseException

Config = TypeVar("Config")


class ConfigError(ValueError):
    """An option has a value that cannot work; the message names the key."""


NO_SUCH_OPTION = "no such option (check its spelling in the tool's conf/*.yaml)"
BAD_OPTION_STATUS = 2  # the exit status of every tool for an option it cannot use


def run_hydra_tool(tool: str, hydra_main: Callable[[], Any]) -> None:
    """Run a tool's ``@hydra.main`` function so that an option Hydra cannot compose (a misspelt
    key, a wrong type, a group option that does not exist, an override it cannot parse) ends
    like one lanelab refuses: one line naming it, exit status 2.

    Hydra would print several lines and exit with 1; with HYDRA_FULL_ERROR it raises instead
    (a user's own HYDRA_FULL_ERROR=0 keeps Hydra's way)."""
    os.environ.setdefault("HYDRA_FULL_ERROR", "1")
    with bad_options_exit(tool):
        hydra_main()


@contextmanager
def bad_options_exit(tool: str) -> Iterator[None]:
    """A ConfigError or a Hydra composition error in the block: ``<tool>: bad option: ...`` on
    stderr and exit status 2."""
    try:
        yield
    except ConfigError as err:
        _exit_bad_option(tool, str(err))
    except HydraException as err:
        _exit_bad_option(tool, hydra_error_line(err))


def options_or_exit(tool: str, cfg: DictConfig, schema: type[Config], validate: Callable[[Config], Config]) -> Config:
    """cfg typed by schema and checked by validate; a mandatory option left out or a bad value
    ends the tool with one line naming the key and exit status 2."""
    try:
        return validate(typed(cfg, schema))
    except MissingMandatoryValue as err:
        print(f"{tool}: missing option {err.full_key}=...", file=sys.stderr)
        sys.exit(BAD_OPTION_STATUS)
    except ConfigError as err:
        _exit_bad_option(tool, str(err))


def _exit_bad_option(tool: str, message: str) -> None:
    print(f"{tool}: bad option: {message}", file=sys.stderr)
    sys.exit(BAD_OPTION_STATUS)


def hydra_error_line(err: HydraException) -> str:
    """One line for what Hydra could not compose, naming the key where Hydra's error does."""
    cause = err.__cause__
    if isinstance(cause, OmegaConfBaseException) and getattr(cause, "full_key", None):
        if isinstance(cause, (ConfigKeyError, AttributeError)):
            return f"{cause.full_key}: {NO_SUCH_OPTION}"
        return f"{cause.full_key}: {str(cause).splitlines()[0]}"
    lines = str(err).split("Config search path:")[0].splitlines()
    text = lines[0].strip() if lines else type(err).__name__
    if isinstance(err, OverrideParseException):
        return f"cannot parse an override: {text}"
    choices = [line.strip() for line in lines[1:] if line.startswith("\t")]
    if isinstance(err, MissingConfigException) and choices:
        return f"{text} (choices: {', '.join(choices)})"
    return " ".join(line.strip() for line in lines if line.strip())


def register_schema(name: str, schema: type) -> None:
    """Make ``schema`` known to Hydra as ``name`` (the first entry of its yaml's defaults list)."""
    ConfigStore.instance().store(name=name, node=schema)


def load_config(config_name: str, schema_name: str, schema: type[Config],
                validate: Callable[[Config], Config], overrides: Sequence[str] = ()) -> Config:
    """Compose ``conf/<config_name>.yaml`` with Hydra overrides and validate it, as its CLI does.

    For scripts, benchmarks and tests that run a tool without the command line.
    """
    register_schema(schema_name, schema)
    with initialize_config_module(config_module="lanelab.conf", version_base="1.3"):
        cfg = compose(config_name=config_name, overrides=list(overrides))
    return validate(typed(cfg, schema))


def typed(cfg: DictConfig, schema: type[Config]) -> Config:
    """The composed config as its schema's dataclass. Refuses keys the schema does not have:
    OmegaConf refuses ``typo=1``, but Hydra adds ``+typo=1`` past its struct flag."""
    check_known_keys(cfg, schema)
    return OmegaConf.to_object(cfg)


def check_known_keys(cfg: DictConfig, schema: type) -> None:
    """ConfigError naming the first key of ``cfg`` that the dataclass ``schema`` (and the
    dataclasses of its fields, recursively) does not declare; fields typed Any are not looked into."""
    unknown = _unknown_keys(OmegaConf.to_container(cfg, resolve=False, throw_on_missing=False), schema, "")
    if unknown:
        raise ConfigError(f"{unknown[0]}: {NO_SUCH_OPTION}")


def _unknown_keys(values: Any, schema: type, prefix: str) -> list[str]:
    hints = typing.get_type_hints(schema)
    found = []
    for key, value in values.items():
        if key not in hints:
            found.append(f"{prefix}{key}")
            continue
        inner = _dataclass_in(hints[key])
        if inner is not None and isinstance(value, dict):
            found += _unknown_keys(value, inner, f"{prefix}{key}.")
    return found


def _dataclass_in(hint: Any) -> type | None:
    """The dataclass a field's type hint names (``X``, ``X | None``), else None."""
    for candidate in (hint, *typing.get_args(hint)):
        if dataclasses.is_dataclass(candidate):
            return candidate
    return None


def check_positive(key: str, value: float | None) -> None:
    """``value`` must be > 0 (None, for an optional key, passes)."""
    if value is not None and not value > 0:
        raise ConfigError(f"{key}={value!r} must be > 0")


def check_choice(key: str, value: str, choices: Sequence[str]) -> None:
    if value not in choices:
        raise ConfigError(f"{key}={value!r} is not one of {', '.join(choices)}")


def check_writable_folder(key: str, value: str | os.PathLike[str]) -> None:
    """``value`` must be a folder this process can make (if missing) and write: a file is written
    and removed in it or in its nearest existing parent, which are left as they were. Catches a
    permission, a read-only file system, a file on the way."""
    path = Path(value).absolute()
    base = next(folder for folder in (path, *path.parents) if folder.exists())
    try:
        if not base.is_dir():
            raise NotADirectoryError(errno.ENOTDIR, f"{base} is a file")
        with tempfile.TemporaryFile(dir=base):
            pass
    except OSError as err:
        raise ConfigError(f"{key}={value}: cannot write there ({err.strerror or err})") from None


def check_existing(key: str, value: str | None, kind: str) -> None:
    """``value`` must name an existing ``kind`` ("folder" or "file"); None passes."""
    if value is None:
        return
    path = Path(value)
    if not (path.is_dir() if kind == "folder" else path.is_file()):
        raise ConfigError(f"{key}={value!r} is not an existing {kind}")
