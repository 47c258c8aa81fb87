"""What every layer of lenticalib shares (filled in by the restructure; see docs/architecture.md)."""
