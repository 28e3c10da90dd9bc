"""Command-line interface of hairinv (click)."""
