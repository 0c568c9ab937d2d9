"""Plugins: a user's own code, loaded by every entry point that runs or resumes a run.

A plugin is a Python module (``mylab.controllers``) or a ``.py`` file that, when it is
imported, adds what it brings to the package's registries: a controller
(``evolution.controllers.register_controller``), a controller input
(``evolution.input_kernels.register_input``), a task (``cyber_rodent.tasks.spec.register``).
What a script registers counts in its own process only; a plugin is named on the command line
(``--plugin MODULE_OR_FILE``) and is loaded in every process that needs it: the command's own,
before any setting is checked, the local workers of a sweep and the Ray workers of a cluster,
and again by ``resume``.

This module only finds, hashes and loads code (standard library only): it knows nothing of
the registries, which the plugin calls itself.

- A plugin is described by a :class:`Plugin`: the name as given (a file by its resolved
  absolute path), its kind (``module`` or ``file``) and the SHA-256 of its source (a module's:
  its ``.py`` file's bytes). A run records it in ``run.json``, so ``resume`` can load it again
  and refuse it when it is missing or its content changed.
- Loading is once per process: loading the same plugin again with the same content is a no-op,
  and the same name with other content is refused (:class:`PluginChanged`), since its
  registrations cannot be undone. A module is imported as usual; a file is executed as a module
  of a stable synthetic name derived from its path and content hash
  (:attr:`Plugin.module_name`), entered in ``sys.modules`` so that pickling and numba find the
  functions it defines.
- A :class:`PluginSource` carries a loaded plugin's source text with its identity: a worker on
  another machine loads exactly the same code from it, without the file, after checking the text
  against the hash.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.machinery
import importlib.util
import linecache
import os
import re
import sys
import types
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

#: What a plugin is: an importable module or a ``.py`` file.
KINDS = ("module", "file")
#: The prefix of the synthetic module names plugin files are loaded under.
MODULE_PREFIX = "cyber_rodent_plugin_"
_SHA256 = re.compile(r"[0-9a-f]{64}")


class PluginError(ValueError):
    """A plugin that cannot be found or loaded: one line, ``NAME: CAUSE``.

    Attributes:
        plugin: the plugin as named (a module name or a path).
        cause: what is wrong, in words.
    """

    def __init__(self, plugin: str, cause: str) -> None:
        super().__init__(f"{plugin}: {cause}")
        self.plugin = plugin
        self.cause = cause


class PluginMissing(PluginError):
    """The plugin's file does not exist, or no module of its name can be imported."""


class PluginChanged(PluginError):
    """The plugin's content differs from the content recorded or already loaded."""


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def short(sha256: str) -> str:
    """The first 12 hex digits of a hash, for messages."""
    return sha256[:12]


@dataclass(frozen=True)
class Plugin:
    """One plugin, as a run records it.

    Attributes:
        name: a module's dotted name, or a file's resolved absolute path.
        kind: ``"module"`` or ``"file"``.
        sha256: the SHA-256 (hex) of its source file's bytes.
    """

    name: str
    kind: str
    sha256: str

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"plugin name must be a non-empty string, got {self.name!r}")
        if self.kind not in KINDS:
            raise ValueError(f"plugin kind must be one of {', '.join(KINDS)}, got {self.kind!r}")
        if not isinstance(self.sha256, str) or not _SHA256.fullmatch(self.sha256):
            raise ValueError(f"plugin sha256 must be 64 lower-case hex digits, got {self.sha256!r}")

    @property
    def module_name(self) -> str:
        """The name of the module the plugin is loaded as: a module's own name; for a file,
        ``cyber_rodent_plugin_<stem>_<hash of its path>_<hash of its content>``, the same in
        every process that loads the same file with the same content."""
        if self.kind == "module":
            return self.name
        stem = re.sub(r"\W", "_", Path(self.name).stem)
        where = _digest(self.name.encode("utf-8"))[:8]
        return f"{MODULE_PREFIX}{stem}_{where}_{short(self.sha256)}"

    def record(self) -> dict[str, str]:
        """The plugin as a JSON object: ``{"name", "kind", "sha256"}``."""
        return {"name": self.name, "kind": self.kind, "sha256": self.sha256}

    @classmethod
    def from_record(cls, record: object) -> Plugin:
        """The plugin a :meth:`record` describes.

        Raises:
            ValueError: not such a record (the message says what is wrong).
        """
        if not isinstance(record, dict) or set(record) != {"name", "kind", "sha256"}:
            raise ValueError(f"a plugin record has exactly name, kind and sha256, got {record!r}")
        return cls(record["name"], record["kind"], record["sha256"])


@dataclass(frozen=True)
class PluginSource:
    """A plugin with its source text: what a worker needs to load exactly the same code.

    Attributes:
        name, kind, sha256: the plugin (:class:`Plugin`).
        text: its source, whose UTF-8 bytes hash to ``sha256``.
    """

    name: str
    kind: str
    sha256: str
    text: str

    def __post_init__(self) -> None:
        self.verify()

    @property
    def plugin(self) -> Plugin:
        """The plugin this is the source of."""
        return Plugin(self.name, self.kind, self.sha256)

    def verify(self) -> None:
        """Check the text against the hash.

        Raises:
            PluginChanged: the text is not the plugin's source.
        """
        actual = _digest(self.text.encode("utf-8"))
        if actual != self.sha256:
            raise PluginChanged(
                self.name,
                f"the source sent does not match its hash (sha256 {short(self.sha256)} "
                f"recorded, {short(actual)} sent)",
            )

    def load(self) -> Plugin:
        """Load the plugin from this text, once per process (the file need not exist here).

        A module plugin whose module is importable here with the same content is imported as
        usual; otherwise the text is executed as that module.

        Raises:
            PluginChanged: the text does not match the hash, or this process loaded other
                content under the plugin's name.
            PluginError: the plugin raised while it was loaded.
        """
        self.verify()
        plugin = self.plugin
        held = _LOADED.get((plugin.kind, plugin.name))
        if held is not None:
            _check_same(held, plugin)
            return held.plugin
        if plugin.kind == "module":
            try:
                here = identify(plugin.name)
            except PluginError:
                here = None
            if here == plugin:
                return _import_module(plugin, self.text)
        return _execute(plugin, self.text)


@dataclass(frozen=True)
class _Loaded:
    """A plugin this process loaded, with the text it loaded."""

    plugin: Plugin
    text: str


#: Every plugin this process loaded, by (kind, name), in load order.
_LOADED: dict[tuple[str, str], _Loaded] = {}


def _is_file(spec: str) -> bool:
    return spec.endswith(".py") or "/" in spec or os.sep in spec


def identify(spec: str) -> Plugin:
    """The plugin ``spec`` names, found and hashed but not run.

    Args:
        spec: a dotted module name (``mylab.controllers``) or the path of a ``.py`` file.

    Raises:
        PluginMissing: no such file, or no importable module of that name.
        PluginError: ``spec`` is neither a module name nor a ``.py`` file, a module without a
            ``.py`` source, or a package of the module raised while it was imported.
    """
    if not isinstance(spec, str) or not spec.strip():
        raise PluginError(repr(spec), "give a module name or the path of a .py file")
    if _is_file(spec):
        path = Path(spec).expanduser().resolve()
        if not path.exists():
            raise PluginMissing(str(path), "no such file")
        if not path.is_file() or path.suffix != ".py":
            raise PluginError(str(path), "not a .py file")
        return Plugin(str(path), "file", _digest(_read(path, str(path))))
    if not all(part.isidentifier() for part in spec.split(".")):
        raise PluginError(spec, "neither a module name nor the path of a .py file")
    held = _LOADED.get(("module", spec))
    if held is not None and _from_text(spec):
        return held.plugin  # loaded from its text here: there is no file to look at
    try:
        found = importlib.util.find_spec(spec)
    except ModuleNotFoundError as err:
        raise PluginMissing(spec, f"no importable module of that name ({err})") from None
    except Exception as err:  # a parent package raised on import
        raise PluginError(spec, f"importing it raised {type(err).__name__}: {err}") from None
    if found is None:
        raise PluginMissing(spec, "no importable module of that name (nor a .py file)")
    origin = found.origin
    if not found.has_location or origin is None or not origin.endswith(".py"):
        raise PluginError(spec, f"its module has no .py source file to record ({origin})")
    return Plugin(spec, "module", _digest(_read(Path(origin), spec)))


def _from_text(name: str) -> bool:
    """Is module ``name`` one :func:`_execute` made from a plugin's text (no loader)?"""
    spec = getattr(sys.modules.get(name), "__spec__", None)
    return spec is not None and spec.loader is None and not spec.has_location


def _read(path: Path, name: str) -> bytes:
    try:
        return path.read_bytes()
    except OSError as err:
        raise PluginError(name, f"cannot read {path}: {err.strerror or err}") from None


def _text(plugin: Plugin) -> str:
    """The plugin's source text as it is on disk now (checked against its hash)."""
    path = Path(plugin.name)
    if plugin.kind == "module":
        found = importlib.util.find_spec(plugin.name)
        path = Path(str(found.origin if found is not None else ""))
    data = _read(path, plugin.name)
    if _digest(data) != plugin.sha256:
        raise PluginChanged(plugin.name, "it changed while it was being loaded")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as err:
        raise PluginError(plugin.name, f"its source is not UTF-8 text ({err})") from None


def _check_same(held: _Loaded, plugin: Plugin) -> None:
    if held.plugin.sha256 != plugin.sha256:
        raise PluginChanged(
            plugin.name,
            f"this process loaded other content of it (sha256 {short(held.plugin.sha256)}), "
            f"not sha256 {short(plugin.sha256)}; a plugin is loaded once per process",
        )


def load_plugin(spec: str, *, sha256: str | None = None) -> Plugin:
    """Load the plugin ``spec`` names from disk, once per process.

    The content is hashed before it runs. Loading a plugin this process already loaded, with
    the same content, is a no-op.

    Args:
        spec: a dotted module name or the path of a ``.py`` file.
        sha256: the content the caller expects (a run's record): other content is refused
            before it runs.

    Returns:
        The plugin loaded.

    Raises:
        PluginMissing: no such file or module.
        PluginChanged: its content is not ``sha256``, or this process loaded other content of
            it (a plugin's registrations cannot be undone).
        PluginError: anything else that stops it: not a module name nor a ``.py`` file, a
            source that is not UTF-8, or an exception the plugin raised (named in the message).
    """
    plugin = identify(spec)
    if sha256 is not None and plugin.sha256 != sha256:
        raise PluginChanged(
            plugin.name,
            f"its content has changed (sha256 {short(sha256)} recorded, {short(plugin.sha256)} "
            "now)",
        )
    held = _LOADED.get((plugin.kind, plugin.name))
    if held is not None:
        _check_same(held, plugin)
        return held.plugin
    text = _text(plugin)
    if plugin.kind == "module":
        return _import_module(plugin, text)
    return _execute(plugin, text)


def load_plugins(specs: Iterable[str]) -> tuple[Plugin, ...]:
    """:func:`load_plugin` of each of ``specs``, in order."""
    return tuple(load_plugin(spec) for spec in specs)


def ensure_loaded(plugin: Plugin) -> Plugin:
    """``plugin`` loaded in this process: a no-op where it is (from disk or from a
    :class:`PluginSource`), else :func:`load_plugin` of its name and hash.

    Raises:
        PluginMissing, PluginChanged, PluginError: as :func:`load_plugin`.
    """
    held = _LOADED.get((plugin.kind, plugin.name))
    if held is not None:
        _check_same(held, plugin)
        return held.plugin
    loaded = load_plugin(plugin.name, sha256=plugin.sha256)
    if loaded.kind != plugin.kind:
        raise PluginError(plugin.name, f"it is a {loaded.kind} here, not a {plugin.kind}")
    return loaded


def loaded_plugins() -> tuple[Plugin, ...]:
    """Every plugin this process loaded, in load order."""
    return tuple(held.plugin for held in _LOADED.values())


def plugin_source(plugin: Plugin) -> PluginSource:
    """The source text this process loaded ``plugin`` from, for a worker to load.

    Raises:
        ValueError: this process did not load ``plugin`` (or loaded other content of it).
    """
    held = _LOADED.get((plugin.kind, plugin.name))
    if held is None or held.plugin != plugin:
        raise ValueError(f"plugin {plugin.name} is not loaded in this process; load it first")
    return PluginSource(plugin.name, plugin.kind, plugin.sha256, held.text)


def plugin_records(plugins: Sequence[Plugin | PluginSource]) -> list[dict[str, str]]:
    """The plugins as a run records them (``run.json``'s ``plugins``)."""
    return [(p.plugin if isinstance(p, PluginSource) else p).record() for p in plugins]


def plugins_from_records(records: object, where: str = "plugins") -> tuple[Plugin, ...]:
    """The plugins of a run's record (``run.json``'s ``plugins``; None: none).

    Raises:
        ValueError: one line naming ``where``: not a list of plugin records.
    """
    if records is None:
        return ()
    if not isinstance(records, list):
        raise ValueError(f"{where} must be a list of plugin records, got {records!r}")
    try:
        return tuple(Plugin.from_record(record) for record in records)
    except ValueError as err:
        raise ValueError(f"{where}: {err}") from None


def _import_module(plugin: Plugin, text: str) -> Plugin:
    """Import a module plugin as usual (its file hashes to ``plugin.sha256``)."""
    try:
        importlib.import_module(plugin.name)
    except Exception as err:
        raise PluginError(plugin.name, f"it raised {type(err).__name__}: {err}") from None
    _LOADED[(plugin.kind, plugin.name)] = _Loaded(plugin, text)
    return plugin


def _execute(plugin: Plugin, text: str) -> Plugin:
    """Run ``text`` as the module :attr:`Plugin.module_name`, entered in ``sys.modules``.

    The source is also entered in :mod:`linecache` under the plugin's file name, so that
    tracebacks and ``inspect`` show it where the file is absent (a Ray worker).
    """
    name = plugin.module_name
    filename = plugin.name if plugin.kind == "file" else f"<plugin {plugin.name}>"
    module = types.ModuleType(name)
    module.__file__ = filename
    module.__spec__ = importlib.machinery.ModuleSpec(name, None, origin=filename)
    if plugin.kind == "module":
        module.__package__ = plugin.name.rpartition(".")[0]
    linecache.cache[filename] = (len(text), None, text.splitlines(keepends=True), filename)
    previous = sys.modules.get(name)
    sys.modules[name] = module
    try:
        code = compile(text.removeprefix("\ufeff"), filename, "exec", dont_inherit=True)
        exec(code, module.__dict__)
    except Exception as err:
        if previous is None:
            sys.modules.pop(name, None)
        else:
            sys.modules[name] = previous
        linecache.cache.pop(filename, None)
        raise PluginError(plugin.name, f"it raised {type(err).__name__}: {err}") from None
    _LOADED[(plugin.kind, plugin.name)] = _Loaded(plugin, text)
    return plugin


__all__ = [
    "KINDS",
    "MODULE_PREFIX",
    "Plugin",
    "PluginChanged",
    "PluginError",
    "PluginMissing",
    "PluginSource",
    "ensure_loaded",
    "identify",
    "load_plugin",
    "load_plugins",
    "loaded_plugins",
    "plugin_records",
    "plugin_source",
    "plugins_from_records",
    "short",
]
