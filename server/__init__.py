"""gaitscope server: the FastAPI app (``app``), its REST routes (``routes/``), websockets, the viser leg
view, settings, the command line (``cli``), the browser's generated wire types (``wire``) and the load
and soak benchmarks (``bench/``)."""
