"""The `galileo-cnc` command line: info, plot, preview, ports (and the console).
"""
