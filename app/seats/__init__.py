"""Who holds a seat: a person in the browser, or an agent (`sim.agents.turns.Agent`) seated by `app.seats.seat`."""
