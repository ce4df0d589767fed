"""The operator station: ``bench station serve``, a web page to run batch acceptance."""
