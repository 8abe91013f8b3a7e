"""Who drives: a person in the browser, or a `DriverPolicy` seated by `app.drivers.seat`."""
