"""The reference implementation of RCML 2.0 / RCTP/2.0 and RSP, and the robots it ships with.

`robots/` holds example robots (an RCML file and its RXID panels each): the paper's pan/tilt
camera and a two-wheeled robot with sensors.
"""
