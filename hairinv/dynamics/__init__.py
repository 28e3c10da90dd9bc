"""Planned stage: see the issues; nothing here yet."""
