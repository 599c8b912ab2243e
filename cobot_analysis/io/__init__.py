"""Readers and writers of raw and published data (C3D, text exports, protocol files, bags)."""
