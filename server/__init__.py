"""gaitscope server: the command line now; the FastAPI app, websockets and viser bridge come next."""
