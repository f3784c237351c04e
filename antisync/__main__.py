from antisync.cli.app import main

main()
