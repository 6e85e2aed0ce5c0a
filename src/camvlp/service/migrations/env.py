"""Alembic's environment for the service's database (see :mod:`camvlp.service.migrate`).

:func:`camvlp.service.migrate.upgrade` hands the connection to migrate in
``config.attributes["connection"]``; run by Alembic's own command line instead
(``alembic -x url=URL ...`` with ``script_location`` pointing here), the URL comes from ``-x``.
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import context

from camvlp.service.db import metadata

config = context.config
connection = config.attributes.get("connection")
if connection is None:  # Alembic's command line
    url = context.get_x_argument(as_dictionary=True).get("url") or config.get_main_option(
        "sqlalchemy.url"
    )
    engine = sa.create_engine(url)
    with engine.begin() as conn:
        context.configure(connection=conn, target_metadata=metadata)
        context.run_migrations()
    engine.dispose()
else:
    context.configure(connection=connection, target_metadata=metadata)
    with context.begin_transaction():
        context.run_migrations()
