"""Settings compared over seeds, each trained and evaluated alike, and their report (the ``compare`` command's job)."""
