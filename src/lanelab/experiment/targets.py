"""Checks of the ``_target_`` nodes of a composed config against what they will call.

Hydra only finds a misspelt key of a ``_target_`` node when the call fails (an "unexpected
keyword argument" without the key's place in the config), and never a wrong type. Here every
node with a ``_target_`` is checked before anything is built: each key must be a parameter of
the target (unless it takes ``**kwargs``), every parameter without a default must be given
(unless ``_partial_``), and each value must fit the parameter's type hint. The schema is the
code itself, so a new model needs no schema of its own.

Type hints are checked as far as they are plain (bool, int, float, str, paths, Optional,
Union, Literal, sequences, mappings, TypedDicts (their keys and no others), classes of other
``_target_`` nodes); hints that say less than that, or that cannot be resolved, accept any value.
"""

from __future__ import annotations

import inspect
import os
import types
from collections.abc import Callable, Iterable, Mapping, MutableMapping, Sequence
from pathlib import Path
from typing import Any, Literal, Union, get_args, get_origin, get_type_hints, is_typeddict

from hydra.utils import get_object
from omegaconf import DictConfig, ListConfig, OmegaConf

HYDRA_KEYS = frozenset({"_target_", "_partial_", "_convert_", "_recursive_", "_args_"})
# Hint -> the config values that fit it (paths are written as strings).
_SCALARS = {bool: (bool,), int: (int,), float: (int, float), str: (str,), Path: (str,), os.PathLike: (str,)}
_SEQUENCES = (list, tuple, set, frozenset, Sequence, Iterable)
_MAPPINGS = (dict, Mapping, MutableMapping)


class TargetError(ValueError):
    """A ``_target_`` node does not fit what it calls; the message starts with the key."""


def check_targets(node: Any, path: str = "") -> None:
    """Check every ``_target_`` node of a config (DictConfig / ListConfig). A node reached
    through an interpolation (``${sampler.train}``) is checked where it is written."""
    if isinstance(node, DictConfig):
        if "_target_" in node:
            _check_call(OmegaConf.to_container(node, resolve=True), path)
        for key in node:
            if not OmegaConf.is_interpolation(node, key):
                check_targets(node[key], _join(path, str(key)))
    elif isinstance(node, ListConfig):
        for i in range(len(node)):
            if not OmegaConf.is_interpolation(node, i):
                check_targets(node[i], f"{path}[{i}]")


def _check_call(node: Mapping[str, Any], path: str) -> None:
    target = _locate(node["_target_"], path)
    try:
        parameters = inspect.signature(target).parameters
    except (TypeError, ValueError):
        return  # a builtin without a signature: nothing to check against
    hints = _hints(target, parameters)
    takes_kwargs = any(p.kind is inspect.Parameter.VAR_KEYWORD for p in parameters.values())
    named = {
        name: p for name, p in parameters.items()
        if p.kind in (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
    }  # fmt: skip
    for key, value in node.items():
        if key in HYDRA_KEYS:
            continue
        if key not in named:
            if not takes_kwargs:
                known = ", ".join(sorted(named))
                raise TargetError(f"{_join(path, key)}: unknown key for {node['_target_']} (its keys: {known})")
            continue
        if not _fits(value, hints[key]):
            where, value, hint = _offending(value, hints[key], _join(path, key))
            raise TargetError(f"{where}={value!r}: wrong type for {node['_target_']}, expected {_describe(hint)}")
    if not node.get("_partial_", False):
        for name, p in named.items():
            if p.default is inspect.Parameter.empty and name not in node:
                raise TargetError(f"{_join(path, name)}: missing, {node['_target_']} needs it")


def _locate(dotted: Any, path: str) -> Any:
    try:
        return get_object(str(dotted))
    except Exception as err:  # hydra raises ImportError or a plain Exception
        raise TargetError(f"{_join(path, '_target_')}={dotted!r}: cannot be imported ({err})") from None


def _hints(target: Any, parameters: Mapping[str, inspect.Parameter]) -> dict[str, Any]:
    """Parameter name -> evaluated type hint (Any where the hint cannot be evaluated:
    names imported only for type checkers, forward references)."""
    function = inspect.unwrap(target.__init__ if inspect.isclass(target) else target)
    namespace = getattr(function, "__globals__", {})
    hints = {}
    for name, p in parameters.items():
        hint = p.annotation
        if isinstance(hint, str):
            try:
                hint = eval(hint, namespace)  # as typing.get_type_hints does, one hint at a time
            except Exception:
                hint = Any
        hints[name] = Any if hint is inspect.Parameter.empty else hint
    return hints


def _fits(value: Any, hint: Any) -> bool:
    """Whether a config value fits a type hint; True for hints this check cannot judge."""
    origin, args = get_origin(hint), get_args(hint)
    if hint is Any:
        return True
    if origin in (Union, types.UnionType):
        return any(_fits(value, arm) for arm in args)
    if origin is Literal:
        return value in args
    if hint is None or hint is type(None):
        return value is None
    if isinstance(value, Mapping) and "_target_" in value:
        return _target_fits(value, hint)
    if is_typeddict(hint):
        return isinstance(value, Mapping) and _typeddict_fits(value, hint)
    if hint in _SCALARS:
        # bool is an int to Python, never to a config
        return isinstance(value, _SCALARS[hint]) and (hint is bool or not isinstance(value, bool))
    kind = origin or hint
    if kind in _SEQUENCES:
        return _sequence_fits(value, kind, args)
    if kind in _MAPPINGS:
        return isinstance(value, Mapping) and (not args or all(_fits(v, args[1]) for v in value.values()))
    return True  # Any, a forward reference, or a class that the config builds in its own way


def _offending(value: Any, hint: Any, path: str) -> tuple[str, Any, Any]:
    """The innermost (key, value, hint) of a value that does not fit, to name it in the error."""
    kind, args = get_origin(hint) or hint, get_args(hint)
    arms = [arm for arm in args if arm is not type(None)]
    if kind in (Union, types.UnionType) and value is not None and len(arms) == 1:
        return _offending(value, arms[0], path)  # an Optional: what the value should have been
    if is_typeddict(kind) and isinstance(value, Mapping) and _has_typeddict_keys(value, kind):
        fields = get_type_hints(kind)  # the keys are right: name the value that is not
        key = next(key for key, item in value.items() if not _fits(item, fields[key]))
        return _offending(value[key], fields[key], f"{path}.{key}")
    if kind in _MAPPINGS and len(args) == 2 and isinstance(value, Mapping):
        for key, item in value.items():
            if not _fits(item, args[1]):
                return _offending(item, args[1], f"{path}.{key}")
    if kind in _SEQUENCES and args and isinstance(value, list) and (kind is not tuple or args[-1] is Ellipsis):
        for i, item in enumerate(value):
            if not _fits(item, args[0]):
                return _offending(item, args[0], f"{path}[{i}]")
    return path, value, hint


def _sequence_fits(value: Any, kind: Any, args: tuple[Any, ...]) -> bool:
    if not isinstance(value, list):
        return False
    if kind is tuple and args and args[-1] is not Ellipsis:
        return len(value) == len(args) and all(_fits(v, a) for v, a in zip(value, args))
    return all(_fits(v, args[0]) for v in value) if args else True


def _typeddict_fits(value: Mapping[str, Any], hint: Any) -> bool:
    fields = get_type_hints(hint)
    return _has_typeddict_keys(value, hint) and all(_fits(item, fields[key]) for key, item in value.items())


def _has_typeddict_keys(value: Mapping[str, Any], hint: Any) -> bool:
    """Whether a mapping has a TypedDict's required keys and no others."""
    return hint.__required_keys__ <= value.keys() <= get_type_hints(hint).keys()


def _target_fits(node: Mapping[str, Any], hint: Any) -> bool:
    """A node that Hydra builds fits a class hint when it builds that class (or a subclass);
    a partial (a factory) fits a callable hint."""
    kind = get_origin(hint) or hint
    if node.get("_partial_", False):
        return kind is Callable or not isinstance(kind, type)
    target = get_object(str(node["_target_"]))
    return not (inspect.isclass(target) and isinstance(kind, type)) or issubclass(target, kind)


def _describe(hint: Any) -> str:
    if is_typeddict(hint):
        return "{" + ", ".join(f"{key}: {_describe(item)}" for key, item in get_type_hints(hint).items()) + "}"
    return hint.__name__ if isinstance(hint, type) else str(hint).replace("typing.", "")


def _join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key
