"""Alembic environment: the URL comes from the caller (app.db.engine.upgrade) or Settings."""

from __future__ import annotations

from alembic import context
from sqlalchemy import engine_from_config, pool

from app.db.models import Base

config = context.config
target_metadata = Base.metadata


def database_url() -> str:
    """alembic.ini's URL when set (app.db.engine sets it), else the server's Settings."""
    if not config.get_main_option("sqlalchemy.url"):
        from app.settings import Settings

        config.set_main_option("sqlalchemy.url", Settings().url.replace("%", "%%"))
    return config.get_main_option("sqlalchemy.url")


def run_migrations() -> None:
    connection = config.attributes.get("connection")
    if connection is not None:
        context.configure(connection=connection, target_metadata=target_metadata, render_as_batch=True)
        with context.begin_transaction():
            context.run_migrations()
        return
    database_url()
    engine = engine_from_config(
        config.get_section(config.config_ini_section, {}), prefix="sqlalchemy.", poolclass=pool.NullPool
    )
    with engine.connect() as conn:
        context.configure(connection=conn, target_metadata=target_metadata, render_as_batch=True)
        with context.begin_transaction():
            context.run_migrations()


if context.is_offline_mode():
    # `alembic upgrade head --sql`: the DDL for the configured database, printed without connecting.
    context.configure(url=database_url(), target_metadata=target_metadata, literal_binds=True, render_as_batch=True)
    with context.begin_transaction():
        context.run_migrations()
else:
    run_migrations()
