"""Readers and writers of lidar file formats."""
