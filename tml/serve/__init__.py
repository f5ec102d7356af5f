"""``tml serve``: the interpreter as a long-running service with an HTTP API and a web page.

:mod:`~tml.serve.storage` keeps missions, runs and logs in a database;
:mod:`~tml.serve.hangar` holds the vehicles and which run flies each;
:mod:`~tml.serve.live` flies one run in its thread; :mod:`~tml.serve.service` is the
service without HTTP; :mod:`~tml.serve.api` is its HTTP shell; ``page/`` is the web page.
"""
