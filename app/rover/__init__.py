"""The rover's server side: its records and tokens (`records`), its live links (`links`), the
backend that puts it in the robot seat (`backend`), each rover trial's overhead tracker
(`tracker_seat`), the `robotslang robot` commands (`commands`) and the software rover that speaks
its wire protocol (`virtual/`). Its socket is `app.routes.robot_ws`."""
