"""Reading the simulator's YAML/TOML configuration files (rigs and scenes)."""

import tomllib
from pathlib import Path

import yaml

__all__ = ["read_config_file", "check_keys"]


def read_config_file(path):
    """Plain data of a ``.yaml``/``.yml`` or ``.toml`` file.

    Raises
    ------
    ValueError
        For another suffix, a missing file or a parse error (with the parser's message).
    """
    path = Path(path)
    if path.suffix.lower() not in (".yaml", ".yml", ".toml"):
        raise ValueError(f"config file must end in .yaml, .yml or .toml, not {path.name!r}")
    if not path.is_file():
        raise ValueError(f"config file {str(path)!r} does not exist")
    text = path.read_text()
    try:
        return tomllib.loads(text) if path.suffix.lower() == ".toml" else yaml.safe_load(text)
    except (tomllib.TOMLDecodeError, yaml.YAMLError) as exc:
        raise ValueError(f"cannot parse {path}: {exc}") from None


def check_keys(mapping, known, where):
    """Raise ValueError unless ``mapping`` is a dict whose keys are all in ``known``
    (typos in config files must not pass silently)."""
    if not isinstance(mapping, dict):
        raise ValueError(f"{where} must be a mapping, not {mapping!r}")
    unknown = sorted(set(mapping) - known)
    if unknown:
        raise ValueError(f"unknown key {unknown[0]!r} in {where}; known keys: "
                         f"{', '.join(sorted(known))}")
