"""The trial's rules, as one pure core: its vocabulary, the seats' actions and the server's
commands, the events, `decide` and `fold`, and what each seat perceives of each event. The live
server, the agent seats, offline self-play and the episode runners all step trials through it; it
imports neither the web app nor the camera stack."""
