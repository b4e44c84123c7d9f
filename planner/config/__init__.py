"""Typed, validated configuration: scenario and target TOML files, and the sanity limits of their values."""
