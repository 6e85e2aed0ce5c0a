"""``camvlp serve``: a positioning service with a site database and a live page.

Sites (a map and one or more cameras) live in a database (SQLite by default, any SQLAlchemy
URL such as PostgreSQL for several machines); photos arrive over HTTP and their fixes are
recorded and streamed to each site's page.
"""

from camvlp.service.app import app_from_env, create_app
from camvlp.service.settings import ServiceSettings

__all__ = ["ServiceSettings", "app_from_env", "create_app"]
