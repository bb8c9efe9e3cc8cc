from fenestra.cli import main

main()
