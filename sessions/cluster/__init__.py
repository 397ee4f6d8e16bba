"""Several gaitscope processes (nodes) on one database: membership, heartbeats, takeover and routing.

:class:`~gaitscope.sessions.cluster.nodes.Nodes` is the whole of it: each node registers and beats in the
``nodes`` table; the proxy asks any node where a request goes (:meth:`Nodes.route`); a node whose beat
stopped is declared gone by the first live node that notices, which then stops its sessions and recovers
their recordings. ``docs/deployment.md`` ("Scale-out") describes the deployment around it.
"""
