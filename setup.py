"""The package list, which pyproject.toml alone cannot say: every package under app/, sim/,
models/ and bench/ (`robotslang bench` runs its figures), plus the checkout's top-level
templates/, static/ and migrations/ shipped inside `app` (app.resources finds them there in a
wheel, and at the top in a checkout). robot_client/ is its own distribution
(robot_client/pyproject.toml)."""

from setuptools import find_packages, setup

SHIPPED_IN_APP = {
    "app.templates": "templates",
    "app.static": "static",
    "app.migrations": "migrations",
    "app.migrations.versions": "migrations/versions",
}

setup(
    packages=find_packages(include=["app", "app.*", "sim", "sim.*", "models", "models.*", "bench", "bench.*"])
    + list(SHIPPED_IN_APP),
    package_dir=SHIPPED_IN_APP,
)
