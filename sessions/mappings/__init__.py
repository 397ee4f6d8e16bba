"""Channel mappings saved per lab: how a rig's files (another tool's MCAP topics and fields, a C3D marker set)
give gaitscope's channels, kept by the rig's signature so that the next file of the same rig maps itself.

:class:`~gaitscope.sessions.mappings.saved.SavedMappings` is the whole of it (table ``channel_mappings``,
migration ``0007_channel_mappings``); the upload routes save the mapping an import used.
"""
