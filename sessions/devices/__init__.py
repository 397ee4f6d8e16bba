"""What a device team runs on the device: a client of gaitscope's device protocol with a torque watchdog.

:mod:`~gaitscope.sessions.devices.watchdog` (pure: what torque to apply given the replies so far) and
:mod:`~gaitscope.sessions.devices.client` (the websocket, pacing, reconnects). Neither imports the server, the
estimators or numpy: ``pip install gaitscope`` and ``from gaitscope.sessions.devices.client import DeviceClient``
is all a controller needs (``websockets`` is the only dependency they use).
:mod:`~gaitscope.sessions.devices.osl` adapts an ``opensourceleg`` SDK leg to the client (it needs that SDK,
and with it numpy).
"""
