from renderloop.cli import main

main()
