from mitlc.cli import main

main()
