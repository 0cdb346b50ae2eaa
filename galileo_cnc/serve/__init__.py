"""`galileo-cnc serve`: the plotter on the network, a third front end over the same
engine as the console and `plot` (backends/: one Machine; plan/: plan_source).

One process owns the machine (service.py: a worker thread runs every machine command,
a poller publishes state, position and progress as events); app.py is the Starlette
application (a JSON API, a server-sent event stream, the page in page/); guard.py
makes it secure by default (a token on every request, no foreign Origin); uploads.py
keeps uploaded files in the user's data folder under names the server chooses; jog.py
is the continuous jog that stops when its client goes away. docs/serve.md.
"""
