"""File formats: the replay CSV, LocoHub tables, MCAP recordings (writer, readers, crash recovery),
model files, and the import of uploaded logs."""
