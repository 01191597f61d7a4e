from mitlc.cli.main import main

main()
