"""Readers and writers of input and output files."""
