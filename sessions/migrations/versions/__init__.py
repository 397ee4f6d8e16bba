"""The revisions, one file each (a package so that a wheel ships them)."""
