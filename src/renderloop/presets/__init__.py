"""Preset YAML files: overrides applied on top of the config defaults."""
