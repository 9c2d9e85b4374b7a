"""Command line interface (`ctrkin --help`)."""
