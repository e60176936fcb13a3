from rcmlconf.cli import main

main()
