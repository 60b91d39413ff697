"""Run-directory readers and writers."""
