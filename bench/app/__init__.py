"""The application: the command line, reports, exports and opening a station."""
