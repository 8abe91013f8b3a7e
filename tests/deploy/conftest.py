"""The machine's PostgreSQL and Redis, as the platform's multi-process tests use them."""

from tests.app.conftest import postgres_url  # noqa: F401  (fixture)
from tests.app.test_relay import redis_url  # noqa: F401  (fixture)
