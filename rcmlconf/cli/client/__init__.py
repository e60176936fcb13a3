"""`rcmlconf client`: the reference RCTP/2.0 client from the command line.

`commands` holds the click commands; the other modules are what they run. This file stays empty
so that `rcmlconf serve`, which shares `interrupts` and `robot`, does not load the commands.
"""
