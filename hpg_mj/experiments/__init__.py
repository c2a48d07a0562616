"""Task files, training runs, metrics and saved agents."""
