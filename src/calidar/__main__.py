from calidar.cli import main

main()
